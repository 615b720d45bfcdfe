"""The knitframe command: --version, plugins, run."""

from __future__ import annotations

import json

import knitframe
from knitframe.plugins import KINDS


def test_version(cli):
    """--version prints the package version."""
    proc = cli("--version")
    assert proc.returncode == 0 and proc.stdout.strip() == f"knitframe {knitframe.__version__}"


def test_plugins_lists_every_kind_with_description_and_package(cli):
    """`knitframe plugins` shows each kind, each plugin's description and its package."""
    proc = cli("plugins")
    assert proc.returncode == 0, proc.stderr
    for kind in KINDS:
        assert f"{kind}:" in proc.stdout
    line = next(l for l in proc.stdout.splitlines() if l.strip().startswith("singal2024"))
    assert "Singal et al. 2024" in line and f"[knitframe {knitframe.__version__}]" in line


def test_plugins_json_matches_registry(cli):
    """`knitframe plugins --json` lists exactly the registry's entries."""
    rows = json.loads(cli("plugins", "--json").stdout)
    names = {(r["kind"], r["name"]) for r in rows}
    assert names == {(e.kind, e.name) for e in knitframe.get_registry().entries()}


def test_run_example_from_cli(cli, tmp_path):
    """`knitframe run --example --out DIR` succeeds and reports what it wrote."""
    proc = cli("run", "--example", "--out", str(tmp_path / "ex"))
    assert proc.returncode == 0, proc.stderr
    assert "wrote" in proc.stdout and (tmp_path / "ex" / "summary.json").exists()


def test_run_needs_a_config_or_example(cli):
    """`knitframe run` without a config is a one-line usage error."""
    proc = cli("run")
    assert (
        proc.returncode == 2
        and proc.stderr.strip() == "knitframe: error: give a CONFIG file or --example (not both)"
    )


def test_yarn_shows_what_the_solvers_read_and_whether_it_is_measured(cli, tmp_path):
    """`knitframe yarn NAME` lists the record's quantities with their status; a config's own yarn too;
    an unknown name is a one-line error with exit code 2."""
    proc = cli("yarn", "cotton")
    assert proc.returncode == 0, proc.stderr
    lines = {line.split()[0] + " " + line.split()[1]: line for line in proc.stdout.splitlines()[1:]}
    assert "measured" in lines["knitted diameter"] and "0.444" in lines["knitted diameter"]
    j_min = next(line for line in proc.stdout.splitlines() if " J_min " in line)
    assert "0.2764" in j_min and "derived" in j_min and "hexagonal packing" in j_min
    rows = json.loads(cli("yarn", "cotton", "--json").stdout)
    assert {r["symbol"] for r in rows} >= {"dk", "E_A", "E_T", "G_A", "EI", "k_line", "J_min", "E_core"}
    (tmp_path / "c.toml").write_text(
        '[yarns.wool]\nlike = "cotton"\ncompaction_limit = 0.4\nmeasured = ["compaction_limit"]\n'
    )
    own = json.loads(cli("yarn", "wool", "--config", "c.toml", "--json").stdout)
    assert next(r for r in own if r["symbol"] == "J_min")["status"] == "measured"
    bad = cli("yarn", "woollen")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "unknown yarn 'woollen'" in bad.stderr
