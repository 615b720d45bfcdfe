"""Plugin loading through pluggy: loud contract errors, tolerant import failures, hermetic switch."""

from __future__ import annotations

import sys
import textwrap
import types
import warnings

import attrs
import pytest

import knitframe
from knitframe.errors import PluginError, UnknownPluginError
from knitframe.plugins import DISABLE_EXTERNAL_ENV, PluginWarning, load_registry


def _fake_dist(tmp_path, monkeypatch, name: str, module_src: str, entry: str = "plugin") -> None:
    """Install a tiny distribution on sys.path: dist-info with a knitframe entry point + its module."""
    mod = f"kf_test_{name}"
    (tmp_path / f"{mod}.py").write_text(textwrap.dedent(module_src))
    info = tmp_path / f"{mod}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {mod}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[knitframe]\n{entry} = {mod}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop(mod, None)


def test_unknown_name_lists_available_names():
    """Looking up an unknown name raises an error listing the registered names of that kind."""
    reg = load_registry()
    with pytest.raises(UnknownPluginError) as e:
        reg["executor"]["nope"]
    assert str(e.value) == f"unknown executor 'nope'; available: {', '.join(sorted(reg['executor']))}"


def test_unknown_kind_lists_kinds():
    """Asking for a kind that does not exist lists the kinds."""
    with pytest.raises(UnknownPluginError, match="available: contact_law"):
        load_registry()["widget"]


def test_misspelled_hook_fails_loudly():
    """A hook implementation whose name matches no hookspec raises at load time (check_pending)."""
    plugin = types.ModuleType("typo_plugin")

    @knitframe.hookimpl
    def register_pattern(register):  # missing trailing "s"
        pass

    plugin.register_pattern = register_pattern
    with pytest.raises(PluginError, match="typo_plugin"):
        load_registry({"typo_plugin": plugin})


def test_broken_third_party_plugin_warns_and_program_keeps_working(tmp_path, monkeypatch):
    """A third-party plugin that raises on import gives a warning naming it; built-ins still load."""
    _fake_dist(tmp_path, monkeypatch, "broken", "raise ImportError('needs libfoo')\n", entry="broken_plugin")
    with pytest.warns(
        PluginWarning, match=r"'broken_plugin' \(kf_test_broken\) failed to load: ImportError: needs libfoo"
    ):
        reg = load_registry(external=True)
    assert "local" in reg["executor"]
    assert ("broken_plugin", "ImportError: needs libfoo") in reg.failed


def test_plugin_that_fails_while_registering_warns(tmp_path, monkeypatch):
    """A plugin whose hook raises is skipped with a warning; the rest of the registry is intact."""
    src = """
        import knitframe

        @knitframe.hookimpl
        def register_executors(register):
            raise RuntimeError("boom")
    """
    _fake_dist(tmp_path, monkeypatch, "raiser", src, entry="raiser")
    with pytest.warns(PluginWarning, match="'raiser'.*RuntimeError: boom"):
        reg = load_registry(external=True)
    assert "local" in reg["executor"]


def test_environment_variable_blocks_external_plugins(tmp_path, monkeypatch):
    """With the blocking variable set, external entry points are not even imported."""
    _fake_dist(
        tmp_path, monkeypatch, "blocked", "raise ImportError('should not be imported')\n", entry="blocked"
    )
    monkeypatch.setenv(DISABLE_EXTERNAL_ENV, "1")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        reg = load_registry()
    assert not reg.failed
    monkeypatch.setenv(DISABLE_EXTERNAL_ENV, "0")
    with pytest.warns(PluginWarning, match="blocked"):
        load_registry()


def test_entries_record_package_and_version():
    """Built-in entries name the knitframe distribution and its version."""
    e = load_registry()["reader"].entry("singal2024")
    assert (e.package, e.version, e.builtin) == ("knitframe", knitframe.__version__, True)
    assert e.plugin == "singal2024"


def test_name_clash_is_reported_not_silently_overwritten():
    """A second plugin registering a taken name is refused with a warning naming both."""
    plugin = types.ModuleType("clash")

    @attrs.frozen
    class Local2:
        name = "local"
        description = "impostor"

    @knitframe.hookimpl
    def register_executors(register):
        register(Local2)

    plugin.register_executors = register_executors
    with pytest.warns(PluginWarning, match="executor 'local' from extra .clash. clashes"):
        reg = load_registry({"clash": plugin})
    assert reg["executor"]["local"].description != "impostor"


def test_register_without_a_name_is_an_error():
    """An implementation with no name attribute and no name= argument is refused."""
    plugin = types.ModuleType("nameless")

    @knitframe.hookimpl
    def register_design_objectives(register):
        register(object())

    plugin.register_design_objectives = register_design_objectives
    with pytest.warns(PluginWarning, match="has no name"):
        load_registry({"nameless": plugin})
