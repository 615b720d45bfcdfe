"""Docs stay true: generated config reference, README commands, CI script."""

from __future__ import annotations

import re

from conftest import ROOT

from knitframe.docgen import configuration_md


def test_configuration_md_is_up_to_date():
    """docs/configuration.md equals what the schemas generate (regenerate with python -m knitframe.docgen)."""
    assert (ROOT / "docs" / "configuration.md").read_text() == configuration_md()


def test_readme_has_the_two_setup_commands_and_ci_runs_the_test_one():
    """The README's two bash blocks install+run the example and install+run the tests; .ci/run calls the
    latter."""
    blocks = re.findall(r"```bash\n(.*?)\n```", (ROOT / "README.md").read_text(), re.S)
    setup = [b for b in blocks if b.startswith("python3 -m venv")]
    assert len(setup) == 2
    assert "knitframe run --example" in setup[0]
    assert "pytest" in setup[1]
    assert setup[1] in (ROOT / ".ci" / "run").read_text()


def test_architecture_doc_lists_every_kind():
    """docs/architecture.md names every plugin kind's hook."""
    from knitframe.plugins import KINDS

    text = (ROOT / "docs" / "architecture.md").read_text()
    assert all(f"`{hook}`" in text for hook in KINDS.values())


def test_readme_config_runs(tmp_path, singal_file):
    """The config shown in the README runs end to end and ends with a fit of the simulation."""
    import json

    import knitframe

    block = re.findall(r"```toml\n(.*?)\n```", (ROOT / "README.md").read_text(), re.S)[0]
    for name in ("cotton-stockinette-x.csv", "cotton-stockinette-y.csv"):
        (tmp_path / name).write_bytes(singal_file(name).read_bytes())
    (tmp_path / "readme.toml").write_text(block)
    res = knitframe.run(tmp_path / "readme.toml", tmp_path / "out")
    assert [s["stage"] for s in res.summary["stages"]] == ["data", "simulate", "fit:simulated"]
    params = json.loads((tmp_path / "out" / "simulated-params.json").read_text())
    assert params["model"] == "hgo" and 0 <= params["theta_deg"] <= 90
    assert [r.provenance.kind for r in res.responses].count("simulation") == 1


def test_every_example_config_in_the_docs_builds():
    """Each docs/examples/*.toml loads and validates into its stages, as `knitframe run` does first."""
    from knitframe.config import load_toml
    from knitframe.pipeline import Pipeline

    configs = sorted((ROOT / "docs" / "examples").glob("*.toml"))
    assert configs
    for path in configs:
        pipeline = Pipeline(load_toml(path), base_dir=path.parent, source=str(path))
        assert pipeline.stages, path.name
