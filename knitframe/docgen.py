"""Generate docs/configuration.md from the config schemas (the attrs classes themselves).

Run ``python -m knitframe.docgen > docs/configuration.md``; a test fails when the file is stale,
so every config key is documented. Field descriptions come from the ``#:`` comment on the field.
"""

from __future__ import annotations

import ast
import inspect
import textwrap
from typing import Any

import attrs

from knitframe.plugins import Registry, load_registry
from knitframe.records import EFFECTS, Fabric, LoadPath, Scene, Yarn
from knitframe.schema import _hints, type_name

__all__ = ["field_docs", "schema_table", "settings_tables", "configuration_md"]

#: plugin kinds selectable from a config, in the order they are documented
CONFIG_KINDS = (
    "solver",
    "contact_law",
    "linear_solver",
    "homogenizer",
    "fitter",
    "reader",
    "executor",
    "design_objective",
    "pattern",
    "yarn_model",
)


def field_docs(cls: type) -> dict[str, str]:
    """``{field: text}`` from the ``#:`` comment block above each field of an attrs class (Sphinx's style).

    A ``#:`` comment at the end of the field's line (the older style, still used by third-party plugins) is
    read when there is no block above the field.
    """
    try:
        src = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    lines = src.splitlines()
    docs: dict[str, str] = {}
    tree = ast.parse(src)
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    for node in body:
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            block: list[str] = []
            i = node.lineno - 2
            while i >= 0 and lines[i].strip().startswith("#:"):
                block.insert(0, lines[i].strip()[2:].strip())
                i -= 1
            # a third-party plugin may still put the text at the end of the field's line
            trailing = [ln for ln in lines[node.lineno - 1 : node.end_lineno] if "#:" in ln]
            if block:
                docs[node.target.id] = " ".join(block)
            elif trailing:
                docs[node.target.id] = trailing[-1].split("#:", 1)[1].strip()
    return docs


def _default(f: attrs.Attribute) -> str:
    d = f.default
    if d is attrs.NOTHING:
        return "required"
    if isinstance(d, attrs.Factory):  # type: ignore[arg-type]
        d = d.factory() if not d.takes_self else "…"
        if attrs.has(type(d)):
            return "see table"
    if isinstance(d, frozenset):
        d = sorted(d)
    if isinstance(d, str):
        return f'`"{d}"`'
    if d is None:
        return "unset"
    return f"`{d!r}`".replace("'", '"')


def schema_table(cls: type) -> str:
    """Markdown table of the init fields of ``cls``: key, type, default, meaning."""
    hints = _hints(cls)
    docs = {}
    for klass in reversed(cls.__mro__):
        if attrs.has(klass):
            docs.update(field_docs(klass))
    rows = ["| key | type | default | meaning |", "|---|---|---|---|"]
    for f in attrs.fields(cls):
        if not f.init:
            continue
        name = f.alias or f.name
        cells = (type_name(hints.get(f.name, Any)), _default(f), docs.get(f.name, ""))
        rows.append(f"| `{name}` | " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(rows)


def _value(v: Any) -> str:
    return f'"{v}"' if isinstance(v, str) else repr(v)


def settings_tables(cls: type, prefix: str) -> list[str]:
    """Markdown lines of the settings tables held in fields of ``cls`` (a field whose default is a fresh
    attrs instance, e.g. ``[solver.newton]``): its named presets, with their values and reasons, and
    its keys."""
    out: list[str] = []
    for f in attrs.fields(cls):
        d = f.default
        if not (isinstance(d, attrs.Factory) and not d.takes_self and attrs.has(d.factory)):  # type: ignore[arg-type]
            continue
        sub, key = d.factory, f.alias or f.name
        out += [f"##### `[{prefix}.{key}]`", "", _doc(sub), ""]
        presets = getattr(sub, "presets", None)
        if presets:
            out += [
                f'Presets: `{key} = "name"`, or `{key} = {{ preset = "name", ... }}` with keys that override',
                "the preset's values.",
                "",
                "- `default`: the values in the table below, measured on the standard cells",
            ]
            for name, p in presets.items():
                values = ", ".join(f"`{k} = {_value(v)}`" for k, v in p.values.items())
                out.append(f"- `{name}` ({values}): {p.reason}")
            out.append("")
        out += [schema_table(sub), ""]
    return out


def _doc(obj: Any) -> str:
    return (getattr(obj, "description", "") or inspect.getdoc(obj) or "").strip().splitlines()[0]


def configuration_md(registry: Registry | None = None) -> str:
    """The full text of docs/configuration.md for the built-in plugins."""
    reg = registry or load_registry(external=False)
    out = [
        "# Configuration reference",
        "",
        "<!-- generated by `python -m knitframe.docgen > docs/configuration.md`; do not edit by hand -->",
        "",
        "A config is a TOML file. Its top-level tables select pipeline stages; the stages present run in",
        "order (import data or simulate → fit → patchwork → design). Units: mm, N, MPa, tension in N/mm;",
        "angles in degrees in configs. Relative paths resolve against the config file's directory.",
        (
            "Any error names the TOML path of the offending key, e.g. "
            "`fabric.stitch_length: must be > 0, got -1`."
        ),
        "",
        'A plugin is chosen by name — `fitter = "lbfgs"` — or by a table with `kind` plus its options —',
        (
            '`fitter = { kind = "mads", max_evals = 500 }`. '
            "The options of every built-in plugin are listed below."
        ),
        "",
        "## `[pipeline]`",
        "",
        "| key | type | default | meaning |",
        "|---|---|---|---|",
        "| `name` | string | config file name | name recorded in summary.json |",
        "| `description` | string | unset | free text |",
        "",
    ]
    stages = reg["stage"]
    for name in sorted(stages, key=lambda n: stages[n].order):
        st = stages[name]
        schema = getattr(st, "schema", None)
        out += [f"## `[{getattr(st, 'table', None) or name}]` stage", "", _doc(st) + ".", ""]
        if st.uses:
            out += [f"Also reads: {', '.join(f'`[{t}]`' for t in st.uses)}.", ""]
        if schema is not None and attrs.has(schema):
            out += [schema_table(schema), ""]
        else:
            out += ["This stage takes no keys of its own.", ""]
    out += ["## Records used in configs", ""]
    for title, cls in (
        ("`[fabric]`", Fabric),
        ("`[fabric.yarn]` (or a yarn name)", Yarn),
        ("`[scene]`", Scene),
        ("`[scene.load]`", LoadPath),
    ):
        out += [f"### {title}", "", _doc(cls), "", schema_table(cls), ""]
    out += ["Effects a scene may ask for (`scene.effects`):", ""]
    out += [f"- `{k}`: {v}" for k, v in EFFECTS.items()] + [""]
    out += ["## Plugin options", ""]
    for kind in CONFIG_KINDS:
        entries = reg[kind].entries()
        if not entries:
            continue
        out += [f"### {kind.replace('_', ' ')}", ""]
        for e in entries:
            out += [f"#### `{e.name}`", "", e.description, ""]
            if isinstance(e.obj, type) and attrs.has(e.obj) and any(f.init for f in attrs.fields(e.obj)):
                out += [schema_table(e.obj), ""]
                out += settings_tables(e.obj, kind)
            elif callable(e.obj) and not isinstance(e.obj, type):
                params = [
                    p
                    for p in inspect.signature(e.obj).parameters.values()
                    if p.kind == p.KEYWORD_ONLY or p.default is not p.empty
                ]
                if params:
                    out += ["| key | default |", "|---|---|"]
                    out += [f"| `{p.name}` | `{p.default!r}` |" for p in params] + [""]
                else:
                    out += ["No options.", ""]
            else:
                out += ["No options.", ""]
    return "\n".join(out).rstrip() + "\n"


if __name__ == "__main__":  # pragma: no cover
    print(configuration_md(), end="")
