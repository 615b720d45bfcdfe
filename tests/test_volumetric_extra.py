"""gmsh and ipctk are the ``volumetric`` extra: fitting and the rod solver work without them, and asking
for the volumetric solver without them is one line saying what to install."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import tomli_w

from knitframe.plugins import get_registry

#: run first in each subprocess: gmsh and ipctk cannot be imported, and every attempt is recorded
BLOCK = textwrap.dedent(
    """\
    import sys

    class Blocked:
        tried = []

        @classmethod
        def find_spec(cls, name, path=None, target=None):
            if name.split(".")[0] in ("gmsh", "ipctk"):
                cls.tried.append(name)
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    for name in ("gmsh", "ipctk"):
        sys.modules.pop(name, None)
    sys.meta_path.insert(0, Blocked)
    """
)


def without_the_extra(script: str, cwd) -> subprocess.CompletedProcess:
    """Run ``script`` after :data:`BLOCK` in a fresh interpreter in ``cwd``."""
    return subprocess.run(
        [sys.executable, "-c", BLOCK + textwrap.dedent(script)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def test_fit_and_the_rod_solver_never_import_gmsh_or_ipctk(tmp_path, singal_file):
    """`knitframe fit` and `knitframe run` of a short rod config work with gmsh and ipctk unimportable, and
    try to import neither."""
    x, y = singal_file("cotton-stockinette-x.csv"), singal_file("cotton-stockinette-y.csv")
    rod = {
        "solver": {"kind": "rod", "segments_per_stitch": 10},
        "fabric": {"pattern": "jersey", "stitch_length": 12, "yarn": "cotton"},
        "scene": {
            "effects": ["large_deformation", "bending", "contact", "prestress"],
            "load": {"kind": "equibiaxial", "max_strain": 0.05, "steps": 1},
        },
    }
    (tmp_path / "rod.toml").write_text(tomli_w.dumps(rod))
    proc = without_the_extra(
        f"""
        import json
        from knitframe.cli import main
        from knitframe_solvers.rod import RodSolver

        fitted = main(["fit", {str(x)!r}, {str(y)!r}, "--model", "hgo", "--fitter", "lbfgs", "--out", "fit"])
        ran = main(["run", "rod.toml", "--out", "rod"])
        print(json.dumps({{"fit": fitted, "run": ran, "tried": Blocked.tried, "solver": RodSolver.name}}))
        """,
        tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out == {"fit": 0, "run": 0, "tried": [], "solver": "rod"}
    assert (tmp_path / "fit" / "params.json").is_file() and (tmp_path / "rod" / "summary.json").is_file()


def test_the_volumetric_solver_without_its_extra_says_what_to_install(tmp_path):
    """`knitframe run` of a volumetric config without gmsh or ipctk exits 2 with one line naming solver.kind
    and the extra, and writes nothing; the Python API raises the same ConfigError, naming what the scene
    needs (no ipctk without the ipc law)."""
    config = {
        "solver": {"kind": "volumetric"},
        "fabric": {"pattern": "jersey", "stitch_length": 11, "yarn": "cotton"},
        "scene": {"effects": ["large_deformation", "bending", "contact", "prestress"]},
    }
    (tmp_path / "cfg.toml").write_text(tomli_w.dumps(config))
    proc = without_the_extra(
        """
        from knitframe.cli import main

        sys.exit(main(["run", "cfg.toml", "--out", "out"]))
        """,
        tmp_path,
    )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert lines[0] == (
        "knitframe: error: cfg.toml: solver.kind: the volumetric solver needs gmsh and ipctk: "
        'pip install "knitframe[volumetric]"'
    )
    assert not (tmp_path / "out").exists()
    proc = without_the_extra(
        """
        from knitframe.errors import ConfigError
        from knitframe.records import Scene
        from knitframe_solvers.volumetric import VolumetricSolver

        try:
            VolumetricSolver(contact_law="mortar").check_extra(Scene(effects=("contact",)))
        except ConfigError as e:
            print(e)
        """,
        tmp_path,
    )
    assert (
        proc.stdout.strip()
        == 'solver.kind: the volumetric solver needs gmsh: pip install "knitframe[volumetric]"'
    )


def test_with_the_extra_the_volumetric_solver_is_accepted():
    """Where gmsh and ipctk are installed (the test extra installs them) the check passes."""
    from knitframe.records import Scene

    get_registry()["solver"]["volumetric"]().check_extra(Scene(effects=("contact",)))
