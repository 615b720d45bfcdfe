"""The layout shows the architecture: plugins use only the public API of their kind, and the tree is
lint-clean."""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys

import pytest
from conftest import ROOT

PLUGINS = ROOT / "plugins"


#: a module or package named in the "Public API" section; ``package.*`` is the package and its modules
ENTRY = re.compile(r"`(knitframe(?:\.[a-z_]+)*(?:\.\*)?)`")
#: a row of its table: ``| what (`knitframe_<kind>`) | `module`, `package.*`, ... |``
ROW = re.compile(r"^\|[^|\n]*`(knitframe_[a-z]+)`[^|\n]*\|([^|\n]*)\|[ \t]*$", re.M)


def public_section() -> str:
    """The text of docs/architecture.md's "Public API" section."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    section = re.search(r"^## Public API\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert section, "docs/architecture.md has no '## Public API' section"
    return section.group(1)


def public_modules() -> set[str]:
    """The modules named in docs/architecture.md's "Public API" section (backticked ``knitframe...``)."""
    return {name.removesuffix(".*") for name in ENTRY.findall(public_section())}


def kind_modules() -> dict[str, set[str]]:
    """What each plugin package may import: its row of the "Public API" table, by package name."""
    rows: dict[str, set[str]] = {}
    for package, cell in ROW.findall(public_section()):
        assert package not in rows, f"docs/architecture.md: two rows of the Public API table for {package}"
        rows[package] = set(ENTRY.findall(cell))
    return rows


def is_module(name: str) -> bool:
    """Whether ``name`` is a module or a package of the tree (the core or a plugin package)."""
    path = name.replace(".", "/")
    return any(
        (base / path).with_suffix(".py").is_file() or (base / path / "__init__.py").is_file()
        for base in (ROOT, PLUGINS)
    )


def plugin_imports() -> list[tuple[str, str, str]]:
    """(file, own plugin package, imported module) for every absolute import in plugins/.

    ``from package import module`` imports that module (``from knitframe import validators`` is
    ``knitframe.validators``); ``from module import name`` imports the module.
    """
    found = []
    for path in sorted(PLUGINS.rglob("*.py")):
        own = path.relative_to(PLUGINS).parts[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [f"{node.module}.{a.name}" for a in node.names]
                names = [name for name in names if is_module(name)]
                if len(names) < len(node.names):
                    names.append(node.module)
            else:
                continue
            found += [(str(path.relative_to(ROOT)), own, name) for name in names]
    return found


def is_public(module: str, public: set[str]) -> bool:
    """A module is public when it is listed, or lies in a listed subpackage, and no part of its name is
    private.

    The top-level package ``knitframe`` stands for its own namespace only, not for every module below it.
    """
    if any(part.startswith("_") for part in module.split(".")):
        return False
    parts = module.split(".")
    return module in public or any(".".join(parts[:k]) in public for k in range(2, len(parts)))


def may_import(module: str, allowed: set[str]) -> bool:
    """Whether a plugin whose row lists ``allowed`` may import ``module``: a listed module, or a module of a
    package listed as ``package.*``, with no part of its name private.

    A package listed without ``.*`` gives what it exports, not its modules.
    """
    if any(part.startswith("_") for part in module.split(".")):
        return False
    return module in allowed or any(
        entry.endswith(".*") and (module == entry[:-2] or module.startswith(entry[:-1])) for entry in allowed
    )


def test_architecture_doc_names_the_public_subpackages():
    """docs/architecture.md lists the top-level package, the shared numerics and the conformance kit."""
    public = public_modules()
    assert {"knitframe", "knitframe.numerics", "knitframe.testing"} <= public
    assert "knitframe.plugins" not in public and "knitframe.pipeline" not in public


def test_plugins_import_only_the_public_api_and_never_another_plugin():
    """Every import of a knitframe module in plugins/ names a public module, and no plugin imports another."""
    public = public_modules()
    packages = {p.name for p in PLUGINS.iterdir() if p.is_dir() and p.name.startswith("knitframe_")}
    bad = []
    for path, own, module in plugin_imports():
        top = module.split(".")[0]
        if top in packages and top != own:
            bad.append(f"{path}: imports the plugin {module}")
        elif top == "knitframe" and not is_public(module, public):
            bad.append(f"{path}: imports the private core module {module}")
    assert not bad, "\n".join(bad)


def test_the_layout_check_catches_a_private_import_and_a_plugin_import():
    """The rule itself: a private module, a private name inside a public package and an unlisted module
    fail."""
    public = {"knitframe", "knitframe.numerics"}
    assert is_public("knitframe.numerics.newton", public)
    assert not is_public("knitframe.numerics._kernels", public)
    assert is_public("knitframe", public) and not is_public("knitframe._version", public)
    assert not is_public("knitframe.pipeline", public)


def test_architecture_doc_has_a_row_for_every_plugin_package():
    """The Public API table has one row per built-in plugin package, and every module a row names exists."""
    rows = kind_modules()
    packages = {p.name for p in PLUGINS.iterdir() if p.is_dir() and p.name.startswith("knitframe_")}
    assert set(rows) == packages
    missing = [
        f"{package}: {entry}"
        for package, allowed in sorted(rows.items())
        for entry in sorted(allowed)
        if not is_module(entry.removesuffix(".*"))
    ]
    assert not missing, "not modules of knitframe: " + ", ".join(missing)


def test_each_plugin_imports_only_the_modules_of_its_kind():
    """Every knitframe module a plugin imports is in its package's row of the Public API table."""
    rows = kind_modules()
    bad = [
        f"{path}: imports {module}, which a plugin of kind {own.removeprefix('knitframe_')} may not import "
        f"(not in the {own} row of docs/architecture.md, 'Public API')"
        for path, own, module in plugin_imports()
        if module.split(".")[0] == "knitframe" and not may_import(module, rows[own])
    ]
    assert not bad, "\n".join(bad)


def test_the_kind_check_catches_a_module_outside_the_kind():
    """The per-kind rule: a listed module and a module of a package listed with ``.*`` pass; a module of a
    package listed without it, an unlisted module and a private one fail."""
    patterns = {"knitframe", "knitframe.geometry"}
    solvers = {"knitframe", "knitframe.numerics.*"}
    assert may_import("knitframe", patterns) and may_import("knitframe.geometry", patterns)
    assert not may_import("knitframe.geometry.cell", patterns)
    assert not may_import("knitframe.numerics.newton", patterns)
    assert may_import("knitframe.numerics", solvers) and may_import("knitframe.numerics.newton", solvers)
    assert may_import("knitframe.numerics.contact.friction", solvers)
    assert not may_import("knitframe.numerics._kernels", solvers)
    assert not may_import("knitframe.numericsx", solvers) and not may_import("knitframe.geometry", solvers)


@pytest.mark.parametrize("args", [["check", "."], ["format", "--check", "."]], ids=["lint", "format"])
def test_ruff_is_clean(args):
    """`ruff check` and `ruff format --check` (configured in pyproject.toml) find nothing in the tree."""
    ruff = shutil.which("ruff", path=str(ROOT / ".venv" / "bin")) or shutil.which("ruff")
    cmd = [ruff] if ruff else [sys.executable, "-m", "ruff"]
    res = subprocess.run([*cmd, *args], cwd=ROOT, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
