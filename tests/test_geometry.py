"""Stitch geometry: arc lengths, periodicity, knit/purl topology, frames, clearance, outputs."""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest
from scipy.integrate import quad

from knitframe import Fabric, GeometryError, get_registry
from knitframe.geometry import Centerline, UnitCell, clearance, frames, image_shifts, strands, write_vtu
from knitframe.testing.patterns import knit_topology

PATTERNS = ("jersey", "garter", "rib", "seed")


def cell_of(pattern: str, sl: float | None = 11, **fabric) -> UnitCell:
    reg = get_registry()
    kw = {"stitch_length": sl} if sl is not None else {}
    return reg["pattern"][pattern]().cell(Fabric(pattern=pattern, yarn=reg["yarn"]["cotton"], **kw, **fabric))


@pytest.mark.parametrize("sl, arc", [(10, 3.9), (11, 4.7), (12, 5.9)])
def test_arc_length_per_stitch_matches_the_stitch_length_table(sl, arc):
    """SL10/11/12 give 3.9/4.7/5.9 mm of yarn per stitch to 1e-6, checked with an independent quadrature."""
    cell = cell_of("jersey", sl)
    assert abs(cell.arc_length_per_stitch - arc) <= 1e-6 * arc
    total = 0.0
    for c in cell.yarns:
        speed = lambda t, c=c: float(np.linalg.norm(c.derivative(np.array([t]))[0]))  # noqa: E731
        total += quad(speed, c.t0, c.t1, limit=400, epsabs=0, epsrel=1e-11)[0]
    assert abs(total / 4 - arc) <= 1e-6 * arc


@pytest.mark.parametrize("pattern", PATTERNS)
def test_every_pattern_hits_the_arc_length(pattern):
    """Each pattern's cell carries 4.7 mm of yarn per stitch at SL11, each row the same."""
    cell = cell_of(pattern)
    lengths = [c.arc_length() for c in cell.yarns]
    assert np.allclose(lengths, 2 * 4.7, rtol=1e-6)


def test_table_override_and_arc_length_option():
    """The stitch-length table can be overridden in the pattern options; arc_length wins over the setting."""
    reg = get_registry()
    jersey = reg["pattern"]["jersey"]
    fab = Fabric(pattern="jersey", yarn=reg["yarn"]["cotton"], stitch_length=11)
    assert jersey(stitch_lengths={"11": 5.2}).cell(fab).arc_length_per_stitch == pytest.approx(5.2, rel=1e-9)
    fab2 = Fabric(pattern="jersey", yarn=reg["yarn"]["cotton"], stitch_length=11, arc_length=5.5)
    assert jersey().cell(fab2).arc_length_per_stitch == pytest.approx(5.5, rel=1e-9)


def test_munden_default_pitches_and_user_override():
    """Pitches default to Munden's ℓ/Kw and ℓ/Kc and follow the fabric's course/wale pitch when given."""
    cell = cell_of("jersey", 11)
    pat = get_registry()["pattern"]["jersey"]()
    assert cell.course_pitch == pytest.approx(4.7 / pat.Kw)
    assert cell.wale_pitch == pytest.approx(4.7 / pat.Kc)
    cell = cell_of("jersey", 11, course_pitch=1.3, wale_pitch=0.8)
    assert (cell.course_pitch, cell.wale_pitch) == (1.3, 0.8)
    assert np.allclose(cell.L1, [2.6, 0, 0]) and np.allclose(cell.L2, [0, 1.6, 0])


@pytest.mark.parametrize("pattern", PATTERNS)
@pytest.mark.parametrize("sl", [10, 12])
def test_position_and_tangent_continue_across_the_cell_boundary(pattern, sl):
    """The end of yarn i at t1 is the start of its paired yarn + L1, in position and unit tangent, to 1e-9."""
    cell = cell_of(pattern, sl)
    for i, j in cell.end_pairs:
        a, b = cell.yarns[i], cell.yarns[j]
        end = a.position(np.array([a.t1]))[0]
        start = b.position(np.array([b.t0]))[0] + cell.L1
        assert np.linalg.norm(end - start) < 1e-9
        ta, tb = a.derivative(np.array([a.t1]))[0], b.derivative(np.array([b.t0]))[0]
        assert np.linalg.norm(ta / np.linalg.norm(ta) - tb / np.linalg.norm(tb)) < 1e-9


@pytest.mark.parametrize("pattern", PATTERNS)
@pytest.mark.parametrize("sl", [10, 11, 12])
def test_knit_purl_topology_matches_the_layout(pattern, sl):
    """Legs pass in front of (knit) or behind (purl) the head of the loop below as the layout says."""
    cell = cell_of(pattern, sl)
    found = {(r, j): k for r, j, k in knit_topology(cell)}
    assert found == {(r, j): cell.layout[r][j] for r in range(2) for j in range(2)}


def test_layouts_alternate_as_the_patterns_say():
    """Garter alternates by row, rib by column, seed by both; jersey is all knit."""
    layouts = {p: cell_of(p).layout for p in PATTERNS}
    assert layouts["jersey"] == (("k", "k"), ("k", "k"))
    assert layouts["garter"] == (("k", "k"), ("p", "p"))
    assert layouts["rib"] == (("k", "p"), ("k", "p"))
    assert layouts["seed"] == (("k", "p"), ("p", "k"))


def test_purl_is_the_knit_loop_mirrored():
    """In garter the purl row is the knit row mirrored through the fabric plane (z -> -z) and shifted by a
    wale."""
    cell = cell_of("garter")
    t = np.linspace(-np.pi, 3 * np.pi, 101)
    k, p = cell.yarns[0].position(t), cell.yarns[1].position(t)
    assert np.allclose(p[:, 2], -k[:, 2]) and np.allclose(p[:, :2] - k[:, :2], [0, cell.wale_pitch])


@pytest.mark.parametrize("pattern", PATTERNS)
def test_frames_are_finite_orthonormal_and_closed(pattern):
    """Rotation-minimising frames have no NaN, are orthonormal and match across the cell boundary."""
    cell = cell_of(pattern, 10)
    fr = frames(cell, 200)
    for f in fr:
        for v in (f.tangent, f.normal, f.binormal):
            assert np.all(np.isfinite(v))
            assert np.allclose(np.linalg.norm(v, axis=1), 1.0)
        assert np.allclose(np.einsum("ij,ij->i", f.tangent, f.normal), 0.0, atol=1e-12)
    for i, j in cell.end_pairs:
        assert np.allclose(fr[i].normal[-1], fr[j].normal[0], atol=1e-9)
        assert np.allclose(fr[i].x[-1], fr[j].x[0] + cell.L1, atol=1e-9)


def test_frames_barely_twist():
    """The frame is rotation-minimising: its twist rate about the tangent is tiny after closure."""
    cell = cell_of("jersey", 11)
    f = frames(cell, 400)[0]
    dn = np.diff(f.normal, axis=0)
    twist = np.abs(np.einsum("ij,ij->i", dn, f.binormal[:-1]))
    ds = np.linalg.norm(np.diff(f.x, axis=0), axis=1)
    # the closing correction spreads the holonomy angle (< π) over the strand
    assert np.max(twist / ds) < np.pi / cell.yarns[0].arc_length() + 0.05


def brute_force_min(cell: UnitCell, n: int, excl: float) -> float:
    """Minimum distance over all sampled pairs (images ±L1, ±L2 included), same-strand neighbours excluded."""
    ks, shifts = image_shifts(cell)
    pts, S, strand = [], [], []
    for s_id, cyc in enumerate(strands(cell)):
        off = 0.0
        for i in cyc:
            c = cell.yarns[i]
            t = np.linspace(c.t0, c.t1, n, endpoint=False)
            pts.append(c.position(t))
            S.append(off + c.arc_coordinate(t))
            strand.append(np.full(n, s_id))
            off += c.arc_length()
    x, S, strand = np.vstack(pts), np.concatenate(S), np.concatenate(strand)
    lam = {s_id: sum(cell.yarns[i].arc_length() for i in cyc) for s_id, cyc in enumerate(strands(cell))}
    best = np.inf
    for (k1, k2), sh in zip(ks, shifts):
        d = np.linalg.norm(x[:, None, :] - (x[None, :, :] + sh), axis=2)
        # every strand here is one self-paired yarn, so image k1 of it is k1 strand lengths further on
        same = (strand[:, None] == strand[None, :]) & (k2 == 0)
        lengths = np.array([lam[s] for s in strand])[None, :]
        ds = np.abs(S[:, None] - (S[None, :] + k1 * lengths))
        d = np.where(same & (ds < excl), np.inf, d)
        best = min(best, float(d.min()))
    return best


@pytest.mark.parametrize("pattern, sl", [("jersey", 11), ("seed", 10), ("rib", 12)])
def test_clearance_agrees_with_brute_force(pattern, sl):
    """The KD-tree + refinement minimum equals a brute-force minimum over all sampled pairs."""
    cell = cell_of(pattern, sl)
    clr = clearance(cell)
    coarse = brute_force_min(cell, 150, clr.self_exclusion)
    fine = brute_force_min(cell, 600, clr.self_exclusion)
    assert clr.minimum <= coarse + 1e-12
    assert abs(clr.minimum - fine) < 2e-3 * cell.dk
    assert all(o.distance < cell.dk for o in clr.overlaps)
    assert clr.overlaps and clr.overlaps[0].distance == clr.minimum


def test_clearance_finds_self_contact_and_ignores_neighbours():
    """A trochoid whose loop passes its own leg reports that self-contact, not its trivial neighbours."""
    b, h = 2.0, 0.1

    def pos(t):
        return np.stack([t - b * np.sin(t), -b * np.cos(t), h * np.sin(t)], axis=-1)

    def der(t):
        return np.stack([1 - b * np.cos(t), b * np.sin(t), h * np.cos(t)], axis=-1)

    line = Centerline("loop", pos, der, -np.pi, np.pi, (2 * np.pi, 0, 0))
    cell = UnitCell(
        "trochoid", (line,), (2 * np.pi, 0, 0), (0, 20.0, 0), 0.15, ((0, 0),), (("k",),), 1.0, np.pi, 10.0
    )
    clr = clearance(cell)
    assert clr.closest.yarns == (0, 0) and clr.closest.image == (0, 0)
    ts = np.linspace(1.6, 2.2, 1201)
    d = np.linalg.norm(pos(ts)[:, None, :] - pos(-ts)[None, :, :], axis=2)
    assert clr.minimum == pytest.approx(d.min(), abs=1e-5)
    assert clr.minimum < cell.dk and clr.overlaps
    assert abs(abs(clr.closest.t[0]) - 1.8955) < 0.1 and clr.closest.t[0] * clr.closest.t[1] < 0


def test_impossible_requests_raise_geometry_error():
    """Too short an arc length, an unknown setting and non-positive input fail with one-line errors."""
    with pytest.raises(GeometryError, match="too short") as e:
        cell_of("jersey", None, arc_length=2.0)
    assert "\n" not in str(e.value)
    with pytest.raises(GeometryError, match="stitch_length 13"):
        cell_of("jersey", 13)
    with pytest.raises(GeometryError, match="do not reach through the row below|too short"):
        cell_of("jersey", None, arc_length=4.0, wale_pitch=2.5)
    with pytest.raises(ValueError, match="arc_length"):
        cell_of("jersey", None, arc_length=-1.0)
    line = cell_of("jersey").yarns[0]
    with pytest.raises(GeometryError, match="end_pairs"):
        UnitCell("x", (line,), (1, 0, 0), (0, 1, 0), 0.2, ((0, 1),), (("k",),), 1.0, 1.0, 1.0)


def test_vtu_files_hold_centerlines_and_tubes(tmp_path):
    """write_vtu writes polylines and closed tube surfaces that meshio reads back without NaN."""
    cell = cell_of("rib")
    paths = write_vtu(cell, tmp_path, n=64, sides=8)
    lines = meshio.read(paths[0])
    tubes = meshio.read(paths[1])
    assert lines.cells_dict["line"].shape == (2 * 64, 2)
    assert tubes.cells_dict["quad"].shape == (2 * 64 * 8, 4)
    assert np.all(np.isfinite(tubes.points))
    r = tubes.points.reshape(2, 65, 8, 3) - lines.points.reshape(2, 65, 1, 3)
    assert np.allclose(np.linalg.norm(r, axis=-1), cell.radius)


def test_cli_geometry_writes_outputs(cli, tmp_path):
    """`knitframe geometry jersey --stitch-length 11 --yarn cotton` writes VTU, PNG and geometry.json."""
    out = tmp_path / "geo"
    res = cli("geometry", "jersey", "--stitch-length", "11", "--yarn", "cotton", "--out", str(out))
    assert res.returncode == 0, res.stderr
    for name in ("centerlines.vtu", "tubes.vtu", "preview.png", "geometry.json"):
        assert (out / name).stat().st_size > 0
    info = json.loads((out / "geometry.json").read_text())
    assert info["arc_length_per_stitch"] == pytest.approx(4.7, rel=1e-6)
    assert info["course_pitch"] > 0 and info["wale_pitch"] > 0
    assert 0 < info["clearance"]["minimum"] < info["dk"]
    assert len(info["clearance"]["overlaps"]) > 0
    assert info["bending_wavenumber"] == pytest.approx(2 * np.pi * info["bending_waves_per_stitch"] / 4.7)


def test_cli_geometry_takes_pattern_options(capsys, tmp_path):
    """`--option fold=1.5` reaches the pattern: the folded rib's cell is deeper and geometry.json says so."""
    from knitframe.cli import main

    for name, extra in (("flat", []), ("folded", ["--option", "fold=1.5"])):
        args = ["geometry", "rib", "--stitch-length", "11", "--course-pitch", "0.8", *extra]
        assert main([*args, "--out", str(tmp_path / name)]) == 0
    flat, folded = (json.loads((tmp_path / n / "geometry.json").read_text()) for n in ("flat", "folded"))
    assert folded["pattern_options"] == {"fold": 1.5} and flat["pattern_options"] == {}
    assert folded["shape"]["fold"] == pytest.approx(1.5 * folded["dk"])
    assert flat["shape"]["fold"] == 0.0


@pytest.mark.parametrize(
    "args, message",
    [
        (["jersey", "--arc-length", "-1"], "--arc-length: must be > 0"),
        (["jersey", "--arc-length", "1.5"], "too short"),
        (["jersy", "--stitch-length", "11"], "unknown pattern 'jersy'"),
        (["jersey", "--stitch-length", "11", "--yarn", "wool"], "unknown yarn 'wool'"),
        (["jersey"], "give stitch_length"),
        (["rib", "--stitch-length", "11", "--option", "fold=-1"], "--option fold: must be in [0.0, 5.0]"),
        (["rib", "--stitch-length", "11", "--option", "fold"], "--option: expects KEY=VALUE"),
        (["rib", "--stitch-length", "11", "--option", "folds=1"], "--option folds: unknown key"),
        (["rib", "--stitch-length", "11", "--option", "fold=nan"], "--option fold: must be finite"),
        (
            ["rib", "--stitch-length", "11", "--option", 'stitch_lengths={"11"=-1}'],
            "--option stitch_lengths.11: must be an arc length > 0 mm",
        ),
    ],
)
def test_cli_geometry_bad_input_is_one_line_exit_2(capsys, tmp_path, args, message):
    """Bad geometry requests print one error line and exit with code 2."""
    from knitframe.cli import main

    assert main(["geometry", *args, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("knitframe: error:")]
    assert len(errors) == 1 and message in errors[0] and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def helix_cell() -> UnitCell:
    """A helix (radius 1 mm, pitch 2 L1) cut into two yarns that continue into each other across the cell."""
    c = 0.5 / np.pi  # x advances L1 = 0.5 mm per half turn (t from 0 to π)

    def pos(t, off=0.0):
        return np.stack([c * t - off, np.cos(t), np.sin(t)], axis=-1)

    def der(t):
        return np.stack([np.full_like(t, c), -np.sin(t), np.cos(t)], axis=-1)

    y0 = Centerline("a", pos, der, 0.0, np.pi, (0.5, 0, 0))
    y1 = Centerline("b", lambda t: pos(t, 0.5), der, np.pi, 2 * np.pi, (0.5, 0, 0))
    return UnitCell(
        "helix", (y0, y1), (0.5, 0, 0), (0, 10.0, 0), 0.15, ((0, 1), (1, 0)), (("k",), ("k",)), 1.0, 0.25, 5.0
    )


def test_bending_wavenumber_of_a_helix_and_of_the_knitted_loops():
    """k_R² = ∮|κ′|²/∮|κ|²: a helix r = (c t, cos t, sin t) gives 1/√(1 + c²) (its curvature vector turns
    at that rate per unit length); the jersey loop bends at about two waves per stitch."""
    from knitframe.geometry import bending_wavenumber, unit_cell

    c = 0.5 / np.pi
    assert bending_wavenumber(helix_cell()) == pytest.approx(1.0 / np.sqrt(1.0 + c * c), rel=1e-5)
    cell = unit_cell(Fabric("jersey", get_registry()["yarn"]["cotton"], stitch_length=12))
    waves = bending_wavenumber(cell) * cell.arc_length_per_stitch / (2 * np.pi)
    assert 1.8 < waves < 2.2
    assert bending_wavenumber(cell, 512) == pytest.approx(bending_wavenumber(cell), rel=2e-3)


def test_two_yarn_strand_frames_and_clearance():
    """A strand of two yarns gets closed frames; its neighbours across the cut are not contacts, its L1 copy
    is."""
    cell = helix_cell()
    assert strands(cell) == [[0, 1]]
    fr = frames(cell, 100)
    assert np.allclose(fr[0].normal[-1], fr[1].normal[0], atol=1e-9)
    assert np.allclose(fr[1].normal[-1], fr[0].normal[0], atol=1e-9)
    assert np.allclose(fr[1].x[-1], fr[0].x[0] + cell.L1, atol=1e-12)
    clr = clearance(cell)
    # brute force: the strand (pitch 2 L1) and its copy shifted by L1 form a double helix
    t = np.linspace(0, 6 * np.pi, 1201)
    r = np.stack([0.5 / np.pi * t, np.cos(t), np.sin(t)], axis=-1)
    s = t * np.hypot(1.0, 0.5 / np.pi)
    own = np.linalg.norm(r[:, None] - r[None], axis=2)
    own[np.abs(s[:, None] - s[None]) < clr.self_exclusion] = np.inf
    other = np.linalg.norm(r[:, None] - (r[None] + cell.L1), axis=2)
    assert clr.minimum == pytest.approx(min(own.min(), other.min()), abs=2e-3)
    assert clr.minimum > 0.4  # the cut between the two yarns is not mistaken for a contact


def test_pattern_options_from_the_fabric_reach_the_cell():
    """Fabric.pattern_options override the pattern's stitch-length table in the cell every solver builds."""
    from knitframe.geometry import unit_cell

    cotton = get_registry()["yarn"]["cotton"]
    base = Fabric("jersey", cotton, stitch_length=11)
    custom = Fabric("jersey", cotton, stitch_length=11, pattern_options={"stitch_lengths": {"11": 5.0}})
    assert unit_cell(base).arc_length_per_stitch == pytest.approx(4.7, rel=1e-6)
    assert unit_cell(custom).arc_length_per_stitch == pytest.approx(5.0, rel=1e-6)


def test_bad_pattern_option_names_its_config_path():
    """An unknown pattern option is a ConfigError at fabric.pattern_options.<key>."""
    from knitframe.errors import ConfigError
    from knitframe.geometry import unit_cell

    with pytest.raises(ConfigError, match=r"^fabric.pattern_options.loops: unknown key"):
        unit_cell(
            Fabric("jersey", get_registry()["yarn"]["cotton"], stitch_length=11, pattern_options={"loops": 3})
        )


def test_a_folded_rib_keeps_its_stitches_and_yarn_and_puts_knit_wales_in_front():
    """fold = F/dk moves knit columns F to the front and purl columns F behind; the arc length per stitch,
    the knit/purl topology and the exact tangent are kept, and fold = 0 is the flat cell."""
    from knitframe.errors import ConfigError
    from knitframe.geometry import unit_cell

    cotton = get_registry()["yarn"]["cotton"]
    flat = unit_cell(Fabric("rib", cotton, stitch_length=11, course_pitch=0.8))
    cell = unit_cell(Fabric("rib", cotton, stitch_length=11, course_pitch=0.8, pattern_options={"fold": 1.5}))
    assert cell.arc_length_per_stitch == pytest.approx(4.7, rel=1e-9)
    assert {(r, j): k for r, j, k in knit_topology(cell)} == {
        (r, j): cell.layout[r][j] for r in range(2) for j in range(2)
    }
    F, D = 1.5 * cell.dk, cell.info["depth"]
    assert cell.info["fold"] == pytest.approx(F)
    for flat_yarn, yarn in zip(flat.yarns, cell.yarns):
        heads = np.array([0.0, 2.0 * np.pi])  # knit column, purl column: z = ±(F - D) there (g = ±1 to 1e-4)
        assert yarn.position(heads)[:, 2] == pytest.approx([F - D, -(F - D)], abs=1e-3 * F)
        assert flat_yarn.position(heads)[:, 2] == pytest.approx([-D, D], abs=1e-3 * F)
        t, h = np.linspace(yarn.t0, yarn.t1, 37), 1e-6
        fd = (yarn.position(t + h) - yarn.position(t - h)) / (2 * h)
        assert np.max(np.abs(fd - yarn.derivative(t))) < 1e-7
    with pytest.raises(ConfigError, match=r"^fabric.pattern_options.fold: "):
        unit_cell(Fabric("rib", cotton, stitch_length=11, pattern_options={"fold": -1.0}))
