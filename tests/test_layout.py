"""The layout shows the architecture: plugins use only the public API, and the tree is lint-clean."""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys

import pytest
from conftest import ROOT

PLUGINS = ROOT / "plugins"


def public_modules() -> set[str]:
    """The modules named in docs/architecture.md's "Public API" section (backticked ``knitframe...``)."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    section = re.search(r"^## Public API\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert section, "docs/architecture.md has no '## Public API' section"
    return set(re.findall(r"`(knitframe(?:\.[a-z_]+)*)`", section.group(1)))


def plugin_imports() -> list[tuple[str, str, str]]:
    """(file, own plugin package, imported module) for every absolute import in plugins/."""
    found = []
    for path in sorted(PLUGINS.rglob("*.py")):
        own = path.relative_to(PLUGINS).parts[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
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


@pytest.mark.parametrize("args", [["check", "."], ["format", "--check", "."]], ids=["lint", "format"])
def test_ruff_is_clean(args):
    """`ruff check` and `ruff format --check` (configured in pyproject.toml) find nothing in the tree."""
    ruff = shutil.which("ruff", path=str(ROOT / ".venv" / "bin")) or shutil.which("ruff")
    cmd = [ruff] if ruff else [sys.executable, "-m", "ruff"]
    res = subprocess.run([*cmd, *args], cwd=ROOT, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
