"""What the pictures say (fit.png, ladder.png, simulated.png, responses.png, the geometry preview) and
two conventions: ``stockinette`` is jersey, and strain limits are fractions."""

from __future__ import annotations

import json
import re
from pathlib import Path

import attrs
import matplotlib
import numpy as np
import pytest

import knitframe
from knitframe.cli import main
from knitframe.errors import ConfigError
from knitframe.fitting import FitResult, plot_fit
from knitframe.geometry import checked_cell, clearance, plot_views
from knitframe.ladder.plots import plot_pareto
from knitframe.pipeline import Pipeline
from knitframe.plugins import PluginWarning, get_registry, load_registry
from knitframe.records import Fabric, LoadPath, Response
from knitframe.schema import build
from knitframe.sweep.validation import MeasuredTable

matplotlib.use("Agg")
from matplotlib.figure import Figure  # noqa: E402

DATA = Path(knitframe.__file__).parent / "examples" / "data"
SINGAL = [str(DATA / "cotton-stockinette-x.csv"), str(DATA / "cotton-stockinette-y.csv")]


@attrs.frozen
class Drawn:
    """What a saved figure shows: its file name and, per axes, title, axis labels and legend texts."""

    name: str
    suptitle: str
    axes: tuple[dict, ...]
    legends: tuple[str, ...]  # figure-level legends


def _drawn(fig: Figure, path) -> Drawn:
    axes = []
    for ax in fig.axes:
        legend = ax.get_legend()
        axes.append(
            {
                "title": ax.get_title(),
                "xlabel": ax.get_xlabel(),
                "ylabel": ax.get_ylabel(),
                "legend": [t.get_text() for t in legend.get_texts()] if legend else [],
                "lines": [ln for ln in ax.get_lines() if len(ln.get_xdata())],
                "collections": list(ax.collections),
            }
        )
    sup = fig._suptitle.get_text() if fig._suptitle is not None else ""
    legends = tuple(t.get_text() for lg in fig.legends for t in lg.get_texts())
    return Drawn(Path(str(path)).name, sup, tuple(axes), legends)


def recording(mp: pytest.MonkeyPatch) -> list[Drawn]:
    """Make ``Figure.savefig`` note what each figure shows before saving it; the notes, in order."""
    seen: list[Drawn] = []
    save = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        seen.append(_drawn(self, fname))
        return save(self, fname, *args, **kwargs)

    mp.setattr(Figure, "savefig", savefig)
    return seen


@pytest.fixture
def figures(monkeypatch):
    """Every figure saved while the test runs, as :class:`Drawn`, in order."""
    return recording(monkeypatch)


def repeated_words(text: str) -> list[str]:
    """The words (letters only, case folded) a text says more than once."""
    words = re.findall(r"[a-z]+", text.lower())
    return sorted({w for w in words if words.count(w) > 1 and len(w) > 1})


def singal_responses() -> list[Response]:
    reader = get_registry()["reader"]["singal2024"]()
    return [r for f in SINGAL for r in reader.read(Path(f))]


FAST_RUN = {
    "data": {"reader": "singal2024", "files": SINGAL},
    "solver": {"kind": "rod", "segments_per_stitch": 8, "prestress_steps": 4},
    "fabric": {"pattern": "stockinette", "arc_length": 11.28, "yarn": "pearl-cotton"},
    "scene": {
        "effects": ["large_deformation", "bending", "contact", "prestress"],
        "load": {"kind": "uniaxial", "direction": "course", "max_strain": 0.05, "steps": 1},
    },
}


@pytest.fixture(scope="module")
def stockinette_run(tmp_path_factory):
    """The example's data and fabric, named stockinette, through a short rod run: the result and the
    figures it saved."""
    out = tmp_path_factory.mktemp("stockinette") / "out"
    with pytest.MonkeyPatch.context() as mp:
        seen = recording(mp)
        result = knitframe.run(FAST_RUN, out)
    return out, result, {d.name: d for d in seen}


# ----------------------------------------------------------------------------------------- pictures
@pytest.mark.parametrize("model", ["hgo", "hgo2m"])
def test_fit_png_right_panel_has_a_legend_for_every_line_and_a_plain_title(figures, tmp_path, model):
    """fit.png's transverse-strain panel gives every line and the shaded band a legend entry and says
    in words what it plots."""
    m = get_registry()["homogenizer"][model]()
    result = FitResult(m, m.x0(), {"overall": 0.1}, fitter="lbfgs")
    plot_fit(tmp_path / "fit.png", result, singal_responses())
    right = figures[-1].axes[1]
    black = [ln for ln in right["lines"] if matplotlib.colors.to_hex(ln.get_color()) == "#000000"]
    measured = [ln.get_label() for ln in right["lines"] if ln not in black]
    assert len(measured) == 2 and all(lab in right["legend"] for lab in measured), right["legend"]
    assert any("standard deviation" in t for t in right["legend"]), right["legend"]
    assert (
        (f"fitted {model}" in right["legend"]) == m.predicts_lateral == bool(black)
    )  # one entry for the model
    assert right["title"].startswith("transverse strain of the free side: measured"), right["title"]


def test_ladder_png_gives_the_error_in_percent(figures, tmp_path):
    """ladder.png plots the NRMSE in % on an axis that says so, as the ladder's tables do."""
    rows = [
        {"rung": "rod:8", "wall_time_s": 2.0, "nrmse_vs_best": 0.25, "nrmse_vs_measured": 0.4},
        {"rung": "rod:16", "wall_time_s": 9.0, "nrmse_vs_best": 0.05, "nrmse_vs_measured": 0.3},
        {"rung": "rod:32", "wall_time_s": 30.0, "nrmse_vs_best": None, "reference": True},
    ]
    plot_pareto(tmp_path / "ladder.png", rows, title="jersey")
    ax = figures[-1].axes[0]
    assert ax["ylabel"].endswith(", %"), ax["ylabel"]
    best = ax["collections"][0].get_offsets()
    assert np.allclose(np.asarray(best)[:, 1], [25.0, 5.0])


def test_simulated_png_title_says_each_thing_once(stockinette_run):
    """simulated.png's title names the solver, the pattern, the stitch size and the yarn once each."""
    _, _, drawn = stockinette_run
    title = drawn["simulated.png"].axes[0]["title"]
    assert title == "rod solver: jersey, 11.28 mm per stitch, pearl-cotton yarn"
    assert repeated_words(title) == []


def test_responses_png_explains_its_shaded_band(stockinette_run):
    """responses.png (and simulated.png) say in the legend that the shaded band is ± one standard
    deviation over the repeats, with their number."""
    _, _, drawn = stockinette_run
    for name in ("responses.png", "simulated.png"):
        legend = drawn[name].axes[0]["legend"]
        band = [t for t in legend if "standard deviation" in t]
        assert band and re.search(r"repeats \(\d+ or \d+\)|over \d+ repeats", band[0]), legend


def test_band_entry_counts_the_repeats_of_one_test(figures, tmp_path):
    """One test averaged over five repeats: the band's legend entry says five."""
    lam = np.linspace(1, 1.2, 8)
    r = Response(
        lam, 1 - 0.2 * (lam - 1), lam - 1, 0 * lam, load="uniaxial-course", n_samples=5, T1_sd=0.01 + 0 * lam
    )
    knitframe.report.plot_responses(tmp_path / "r.png", [r])
    assert "shaded: ± 1 standard deviation over 5 repeats" in figures[-1].axes[0]["legend"]


def test_geometry_preview_marks_the_places_closer_than_dk(figures, tmp_path, capsys):
    """The geometry preview circles the places closer than dk in red, in every view, and its legend gives
    their count as the command prints it."""
    out = tmp_path / "geo"
    assert main(["geometry", "jersey", "--stitch-length", "11", "--yarn", "cotton", "--out", str(out)]) == 0
    count = int(re.search(r"(\d+) places closer than dk", capsys.readouterr().out).group(1))
    preview = next(d for d in figures if d.name == "preview.png")
    assert len(preview.legends) == 1 and preview.legends[0].startswith(f"{count} places per cell "), preview
    for ax in preview.axes:
        marks = [c for c in ax["collections"] if len(c.get_offsets()) == 4 * count]  # 2x2 cells
        assert marks and np.allclose(marks[0].get_edgecolor()[0][:3], (1, 0, 0)), ax["title"]


def test_geometry_preview_without_close_places_marks_the_closest(figures, tmp_path):
    """A cell with no place closer than dk gets its closest place circled, and the legend says none is
    closer."""
    reg = get_registry()
    cell = checked_cell(Fabric(pattern="jersey", yarn=reg["yarn"]["cotton"], stitch_length=12), reg)
    clr = attrs.evolve(clearance(cell), overlaps=())
    plot_views(cell, tmp_path / "preview.png", clearance=clr)
    (text,) = figures[-1].legends
    assert text.startswith("no place closer than dk"), text
    assert len(figures[-1].axes[0]["collections"][-1].get_offsets()) == 4


# -------------------------------------------------------------------------------------- conventions
def test_a_config_with_pattern_stockinette_runs_as_jersey(stockinette_run):
    """`[fabric] pattern = "stockinette"` runs, and its outputs record the pattern as jersey."""
    out, result, _ = stockinette_run
    summary = json.loads((out / "summary.json").read_text())
    assert "jersey" in json.dumps(summary) and "rod jersey" in result.results["simulate"]["label"]
    assert "stockinette " not in (out / "simulated.csv").read_text()


def test_geometry_of_stockinette_is_jersey(tmp_path, capsys):
    """`knitframe geometry stockinette` builds the jersey cell and records it as jersey."""
    out = tmp_path / "geo"
    assert main(["geometry", "stockinette", "--stitch-length", "11", "--out", str(out)]) == 0
    assert capsys.readouterr().out.startswith("jersey: 4.7 mm/stitch")
    assert json.loads((out / "geometry.json").read_text())["pattern"] == "jersey"


def test_a_sweep_point_of_stockinette_is_a_jersey_point(tmp_path):
    """A sweep grid naming stockinette builds jersey points."""
    config = {
        "sweep": {
            "grid": {"pattern": ["stockinette"], "stitch_length": [11], "yarn": ["cotton"]},
            "solver": {"kind": "rod"},
            "scene": {"effects": ["large_deformation", "bending", "contact", "prestress"]},
            "fit": {"model": "hgo"},
        }
    }
    (stage,) = Pipeline(config, base_dir=tmp_path).stages
    (point,) = stage.points
    assert point.stage.fabric.pattern == "jersey" and point.label == "jersey SL11 cotton"


def test_an_alias_that_clashes_with_a_registered_name_is_refused():
    """A plugin whose pattern takes an alias that is already a pattern's name fails to register, saying
    what it clashes with."""

    class Tight:
        name = "tight-jersey"
        aliases = ("jersey",)

    class Plugin:
        @knitframe.hookimpl
        def register_patterns(self, register):
            register(Tight)

    with pytest.warns(PluginWarning, match="pattern 'jersey' from extra .* clashes with"):
        reg = load_registry({"tight": Plugin()}, external=False)
    assert "tight-jersey" not in reg["pattern"] and reg["pattern"].canonical("stockinette") == "jersey"


@pytest.mark.parametrize(
    "where, build_it",
    [
        ("max_strain", lambda: build(LoadPath, {"kind": "uniaxial", "max_strain": 30}, "scene.load")),
        (
            "patchwork.max_strain",
            lambda: build(
                get_registry()["stage"]["patchwork"].schema, {"regions": [], "max_strain": 30}, "patchwork"
            ),
        ),
        (
            "measured.max_strain",
            lambda: build(MeasuredTable, {"files": ["x.csv"], "max_strain": 30}, "sweep.points[0].measured"),
        ),
    ],
)
def test_a_strain_limit_of_30_says_it_is_a_fraction(where, build_it):
    """A strain limit of 30 (meant as %) is refused with a message saying the value is a fraction."""
    with pytest.raises(ConfigError) as e:
        build_it()
    assert str(e.value).endswith(f"{where}: must be in (0.0, 5.0] (a fraction: 0.3 = 30 %), got 30")


def test_a_run_config_with_max_strain_30_says_it_is_a_fraction(tmp_path):
    """`[scene] load = { max_strain = 30 }` in a run config names the key and says the strain is a
    fraction."""
    config = {**FAST_RUN, "scene": {**FAST_RUN["scene"], "load": {"kind": "equibiaxial", "max_strain": 30}}}
    with pytest.raises(ConfigError, match=r"scene\.load\.max_strain: .*\(a fraction: 0\.3 = 30 %\), got 30"):
        Pipeline(config, base_dir=tmp_path)
