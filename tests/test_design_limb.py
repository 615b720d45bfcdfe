"""The limb input for garment design (knitframe.garment.limb): scans, measurements, the example arm."""

from __future__ import annotations

import time
import warnings

import meshio
import numpy as np
import pytest
import trimesh
from scipy import integrate

from knitframe.errors import ConfigError, DataError, GeometryError, KnitframeWarning
from knitframe.garment.limb import (
    EXAMPLE_ARM_MEASUREMENTS,
    Limb,
    ellipse_semi_axes,
    example_arm,
    load_limb,
    loop_curvature_radius,
)

R = 50.0
H = 300.0


def rigid(seed: int, flip: bool = False) -> np.ndarray:
    """A reproducible rotation + translation (4x4), optionally turned end over end first."""
    m = trimesh.transformations.random_rotation_matrix(np.random.default_rng(seed).random(3))
    m[:3, 3] = np.random.default_rng(seed + 100).uniform(-200, 200, 3)
    if flip:
        m = m @ trimesh.transformations.rotation_matrix(np.pi, [1, 0, 0])
    return m


def save(mesh: trimesh.Trimesh, path) -> str:
    mesh.export(str(path))
    return str(path)


def frustum(r0: float, r1: float, height: float = H, sections: int = 128) -> trimesh.Trimesh:
    """A truncated cone (radius r0 at z = -h/2, r1 at z = +h/2) from a cylinder's vertices."""
    m = trimesh.creation.cylinder(radius=1.0, height=height, sections=sections)
    v = m.vertices.copy()
    t = (v[:, 2] + height / 2) / height
    v[:, :2] *= (r0 + (r1 - r0) * t)[:, None]
    return trimesh.Trimesh(v, m.faces, process=False)


def turning(limb: Limb) -> np.ndarray:
    """(n_stations, n_around) z-component along the axis of (p_j - c) x (p_j+1 - c), c = centroid."""
    rel = limb.sections - limb.centroid[:, None, :]
    return np.cross(rel, np.roll(rel, -1, axis=1)) @ limb.axis_direction


def raises_data_error(path, match: str, **kwargs) -> DataError:
    with pytest.raises(DataError) as info:
        Limb.from_scan(path, **kwargs)
    err = info.value
    text = str(err)
    assert "\n" not in text and err.exit_code == 2
    assert text.startswith(str(path) + ": "), text
    assert match in text, text
    return err


# ----------------------------------------------------------------------------------------------
# scans: geometry
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("flip", [False, True], ids=["upright", "upside-down"])
def test_scanned_cylinder(tmp_path, flip):
    """A rotated, translated STL cylinder of radius R gives 2πR to 0.5 %, curvature radius R to 1 %, its axis
    and equal station steps."""
    tf = rigid(3, flip)
    mesh = trimesh.creation.cylinder(radius=R, height=H, sections=100, transform=tf)
    limb = Limb.from_scan(save(mesh, tmp_path / "cyl.stl"), n_stations=21, n_around=64)
    assert limb.sections.shape == (21, 64, 3) and limb.sections.dtype == np.float64
    assert np.abs(limb.circumference / (2 * np.pi * R) - 1).max() < 5e-3
    assert np.abs(limb.curvature_radius / R - 1).max() < 1e-2
    assert np.abs(limb.equivalent_radius / R - 1).max() < 5e-3
    assert abs(abs(limb.axis_direction @ tf[:3, 2]) - 1) < 1e-9
    steps = np.diff(limb.positions)
    assert np.allclose(steps, 0.9 * H / 20, rtol=1e-5)
    # the axis passes through the cylinder's centre line; centroids lie on it
    rel = limb.centroid - tf[:3, 3]
    assert np.linalg.norm(rel - np.outer(rel @ tf[:3, 2], tf[:3, 2]), axis=1).max() < 1e-6 * H
    # loops counter-clockwise seen from station 0 towards the last (negative turning about the axis)
    assert (turning(limb) < 0).all()
    # point 0 of every loop at the same azimuth
    rel0 = limb.sections[:, 0] - limb.centroid
    rel0 /= np.linalg.norm(rel0, axis=1)[:, None]
    assert (rel0 @ rel0[0]).min() > 1 - 1e-9
    # points equally spaced by arc length along each loop
    chords = np.linalg.norm(np.roll(limb.sections, -1, axis=1) - limb.sections, axis=2)
    assert np.ptp(chords) < 1e-2 * chords.mean()
    assert limb.source == "scan: cyl.stl" and limb.name == "cyl" and limb.notes == ()


@pytest.mark.parametrize("small_end_up", [False, True])
def test_scanned_cone_linear_and_small_end_first(tmp_path, small_end_up):
    """A truncated cone gives circumferences linear along the axis, and station 0 (distal) is its small end
    whichever way it lies."""
    r0, r1 = (60.0, 30.0) if small_end_up else (30.0, 60.0)
    tf = rigid(7)
    mesh = frustum(r0, r1)
    mesh.apply_transform(tf)
    limb = Limb.from_scan(save(mesh, tmp_path / "cone.stl"), n_stations=31)
    c = limb.circumference
    fit = np.polyfit(limb.positions, c, 1)
    assert np.abs(np.polyval(fit, limb.positions) - c).max() < 1e-3 * c.mean()
    assert fit[0] > 0 and c[0] < c[-1]
    # slope of the true cone: 2π (r_big - r_small)/H per mm
    assert fit[0] == pytest.approx(2 * np.pi * 30.0 / H, rel=2e-3)
    small_end_axis = tf[:3, 2] * (-1 if small_end_up else 1)  # from small to big end
    assert limb.axis_direction @ small_end_axis == pytest.approx(1.0, abs=1e-9)
    assert limb.named_stations == {"distal": 0, "largest": 30, "top": 30}


def test_scan_of_the_example_arm_gives_back_its_shape(tmp_path):
    """An open-ended, noisy triangulated scan of the example arm, rotated, gives back its circumferences (0.5
    %) with the wrist first."""
    fine = example_arm(n_stations=211, n_around=128)
    quads = fine.quads()
    tris = np.concatenate((quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]))
    rng = np.random.default_rng(0)
    points = fine.sections.reshape(-1, 3) + rng.normal(scale=0.05, size=(fine.sections.size // 3, 3))
    scan = trimesh.Trimesh(points, tris, process=False)  # no caps: a scan is open at both ends
    tf = rigid(6, flip=True)
    scan.apply_transform(tf)
    limb = Limb.from_scan(save(scan, tmp_path / "arm.ply"), n_stations=41, n_around=64)
    assert limb.axis_direction @ tf[:3, 2] == pytest.approx(1.0, abs=1e-4)  # wrist -> upper arm
    z = limb.positions + 0.05 * 420.0
    expected = np.interp(z, fine.positions, fine.circumference)
    assert np.abs(limb.circumference / expected - 1).max() < 5e-3
    assert (limb.curvature_radius > 0).all() and np.isfinite(limb.curvature_radius).all()
    assert limb.named_stations["largest"] == 40


def test_axis_and_reference_arguments_override_the_detection(tmp_path):
    """axis= is taken as the distal -> proximal direction as given, and reference= sets the azimuth of point
    0."""
    tf = rigid(8)
    mesh = frustum(30.0, 60.0)
    mesh.apply_transform(tf)
    path = save(mesh, tmp_path / "cone.stl")
    down = -tf[:3, 2] + 1e-3 * tf[:3, 0]  # big end first, slightly off the true axis
    limb = Limb.from_scan(path, axis=down, n_stations=11)
    assert np.allclose(limb.axis_direction, down / np.linalg.norm(down))
    assert limb.circumference[0] > limb.circumference[-1]
    assert (turning(limb) < 0).all()
    ref = tf[:3, 1] + tf[:3, 2]  # projected perpendicular to the axis: tf y
    limb = Limb.from_scan(path, reference=ref, n_stations=11)
    rel0 = limb.sections[:, 0] - limb.centroid
    assert np.allclose(rel0 / np.linalg.norm(rel0, axis=1)[:, None], tf[:3, 1], atol=1e-6)
    assert load_limb(path, n_stations=11, reference=ref).sections == pytest.approx(limb.sections)
    with pytest.raises(ConfigError, match="reference: must not be parallel to the axis"):
        Limb.from_scan(path, reference=tf[:3, 2])
    with pytest.raises(ConfigError, match="trim: must be in"):
        Limb.from_scan(path, trim=0.5)
    with pytest.raises(ConfigError, match="units: must be one of"):
        Limb.from_scan(path, units="inch")


def test_obj_and_ply_read_the_same_as_stl(tmp_path):
    """The same frustum saved as STL, OBJ and PLY gives the same limb."""
    mesh = frustum(35.0, 55.0)
    mesh.apply_transform(rigid(11))
    limbs = [
        Limb.from_scan(save(mesh, tmp_path / f"arm.{ext}"), n_stations=11, n_around=32)
        for ext in ("stl", "obj", "ply")
    ]
    for other in limbs[1:]:
        assert np.allclose(other.sections, limbs[0].sections, atol=1e-4)
        assert np.allclose(other.circumference, limbs[0].circumference, rtol=1e-7)
    assert [lb.source for lb in limbs] == ["scan: arm.stl", "scan: arm.obj", "scan: arm.ply"]


def test_meshio_format_is_read(tmp_path):
    """A VTU surface (a format trimesh reads through meshio) gives the same limb as the STL."""
    mesh = frustum(35.0, 55.0)
    meshio.write(str(tmp_path / "arm.vtu"), meshio.Mesh(mesh.vertices, [("triangle", mesh.faces)]))
    a = Limb.from_scan(tmp_path / "arm.vtu", n_stations=11, n_around=32)
    b = Limb.from_scan(save(mesh, tmp_path / "arm.stl"), n_stations=11, n_around=32)
    assert np.allclose(a.circumference, b.circumference, rtol=1e-7)


def test_metres_scan_is_converted_with_a_notice_and_a_warning(tmp_path):
    """A cylinder 0.3 long (metres) is scaled by 1000 with a one-line notice and a KnitframeWarning; units=
    forces the scale."""
    mesh = trimesh.creation.cylinder(radius=R / 1000, height=H / 1000, sections=128)
    path = save(mesh, tmp_path / "arm_m.stl")
    with pytest.warns(KnitframeWarning, match="converted from metres"):
        limb = Limb.from_scan(path)
    assert (
        len(limb.notes) == 1
        and limb.notes[0].startswith("converted from metres")
        and "\n" not in limb.notes[0]
    )
    assert limb.circumference.mean() == pytest.approx(2 * np.pi * R, rel=5e-3)
    assert limb.positions[-1] == pytest.approx(0.9 * H, rel=1e-5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        forced = Limb.from_scan(path, units="m")
        as_mm = Limb.from_scan(path, units="mm")
    assert np.allclose(forced.sections, limb.sections)
    assert as_mm.notes == () and as_mm.circumference.mean() == pytest.approx(2 * np.pi * R / 1000, rel=5e-3)
    mm = Limb.from_scan(
        save(trimesh.creation.cylinder(radius=R, height=H, sections=128), tmp_path / "arm_mm.stl")
    )
    assert mm.notes == () and mm.positions[-1] == pytest.approx(0.9 * H, rel=1e-5)


def test_elliptic_cylinder_curvature_matches_the_analytic_radius(tmp_path):
    """An elliptic cylinder (a = 60, b = 36 mm) has ρ = (a²sin²t + b²cos²t)^{3/2}/(ab) to 2 %, and point 0
    sits on its major axis."""
    a, b = 60.0, 36.0
    mesh = trimesh.creation.cylinder(radius=1.0, height=400.0, sections=256)
    mesh.apply_scale([a, b, 1.0])
    tf = rigid(5)
    mesh.apply_transform(tf)
    limb = Limb.from_scan(save(mesh, tmp_path / "ellcyl.stl"), n_around=64)
    rel = limb.sections - limb.centroid[:, None, :]
    u, v = rel @ tf[:3, 0], rel @ tf[:3, 1]
    t = np.arctan2(v / b, u / a)
    rho = (a**2 * np.sin(t) ** 2 + b**2 * np.cos(t) ** 2) ** 1.5 / (a * b)
    assert np.abs(limb.curvature_radius / rho - 1).max() < 2e-2
    assert limb.curvature_radius.min() == pytest.approx(b**2 / a, rel=2e-2)
    assert limb.curvature_radius.max() == pytest.approx(a**2 / b, rel=2e-2)
    # the reference azimuth is the widest transverse direction: point 0 at an end of the major axis
    assert np.allclose(np.abs(u[:, 0]), a, rtol=1e-3) and np.abs(v[:, 0]).max() < 1e-3 * a
    ell = integrate.quad(lambda s: np.sqrt(a**2 * np.sin(s) ** 2 + b**2 * np.cos(s) ** 2), 0, 2 * np.pi)[0]
    assert np.allclose(limb.circumference, ell, rtol=5e-4)


def test_curvature_radius_is_signed_convex_positive_concave_negative():
    """A section with a dent has negative curvature radius in the dent and positive elsewhere; a circle gives
    R exactly."""
    n = 128
    th = 2 * np.pi * np.arange(4096) / 4096
    r = 40.0 * (1 - 0.25 * np.exp(-(((th - np.pi) / 0.3) ** 2)))
    dense = np.column_stack((r * np.cos(th), r * np.sin(th)))
    seg = np.linalg.norm(np.roll(dense, -1, 0) - dense, axis=1)
    s = np.concatenate(([0], np.cumsum(seg)))
    closed = np.vstack((dense, dense[:1]))
    si = s[-1] * np.arange(n) / n
    loop = np.column_stack((np.interp(si, s, closed[:, 0]), np.interp(si, s, closed[:, 1])))
    rho = loop_curvature_radius(loop)
    angle = np.arctan2(loop[:, 1], loop[:, 0]) % (2 * np.pi)
    assert (rho[np.abs(angle - np.pi) < 0.05] < 0).all()
    assert (rho[np.abs(angle - np.pi) > 1.0] > 0).all()
    circle = 25.0 * np.column_stack(
        (np.cos(2 * np.pi * np.arange(16) / 16), np.sin(2 * np.pi * np.arange(16) / 16))
    )
    assert np.allclose(loop_curvature_radius(circle), 25.0, rtol=1e-12)
    assert np.allclose(loop_curvature_radius(circle, max_harmonic=2), 25.0, rtol=1e-12)


def test_limb_record_checks_its_contract():
    """The Limb constructor refuses clockwise loops, loops off their station plane and non-increasing
    stations."""
    good = Limb.from_measurements([0, 100], [160, 200], n_stations=3, n_around=16)
    with pytest.raises(GeometryError, match="clockwise"):
        Limb("x", good.sections[:, ::-1], good.axis_origin, good.axis_direction)
    with pytest.raises(GeometryError, match="strictly increasing"):
        Limb("x", good.sections[::-1], good.axis_origin, good.axis_direction)
    tilted = good.sections.copy()
    tilted[1, 0, 2] += 1.0
    with pytest.raises(GeometryError, match="not in a plane"):
        Limb("x", tilted, good.axis_origin, good.axis_direction)
    with pytest.raises(GeometryError, match="non-finite"):
        Limb(
            "x",
            np.where(tilted == tilted.max(), np.nan, good.sections),
            good.axis_origin,
            good.axis_direction,
        )
    assert not good.sections.flags.writeable


def test_to_vtu_writes_the_quad_surface_with_cell_data(tmp_path):
    """to_vtu writes (n_stations-1)·n_around outward quads on the section points with per-quad fields; a
    wrong-length field writes nothing."""
    limb = example_arm(n_stations=9, n_around=16)
    field = np.arange(8 * 16, dtype=np.float64)
    limb.to_vtu(tmp_path / "arm.vtu", cell_data={"pressure": field})
    back = meshio.read(tmp_path / "arm.vtu")
    assert np.allclose(back.points, limb.sections.reshape(-1, 3))
    (block,) = back.cells
    assert block.type == "quad" and block.data.shape == (8 * 16, 4)
    assert np.allclose(back.cell_data["pressure"][0], field)
    p = back.points[block.data]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 3] - p[:, 0])
    centre = limb.centroid[np.repeat(np.arange(8), 16)]
    assert (np.einsum("ij,ij->i", normal, p[:, 0] - centre) > 0).all()
    with pytest.raises(ValueError, match="one per quad"):
        limb.to_vtu(tmp_path / "bad.vtu", cell_data={"pressure": field[:-1]})
    assert not (tmp_path / "bad.vtu").exists()


# ----------------------------------------------------------------------------------------------
# measurements and the example arm
# ----------------------------------------------------------------------------------------------


def test_from_measurements_reproduces_circumferences_exactly():
    """Measured circumferences are reproduced at their positions with exact ellipse perimeters, and PCHIP
    stays monotone between them."""
    pos = [0.0, 90.0, 190.0, 270.0, 420.0]
    circ = [160.0, 205.0, 250.0, 245.0, 315.0]
    ratio = [0.6, 0.75, 0.85, 0.9, 1.0]
    limb = Limb.from_measurements(pos, circ, ellipticity=ratio, n_stations=41, n_around=64)
    at = np.searchsorted(limb.positions, pos)
    assert np.allclose(limb.positions[at], pos, rtol=0, atol=1e-12)
    assert np.allclose(limb.circumference[at], circ, rtol=1e-10)
    # independent check of the ellipse: semi-axes from the points, perimeter by quadrature
    for i, c, k in zip(at, circ, ratio):
        x = limb.sections[i] - limb.centroid[i]
        a, b = np.abs(x[:, 0]).max(), np.abs(x[:, 1]).max()
        assert b / a == pytest.approx(k, rel=1e-9)
        quad = integrate.quad(
            lambda s, a=a, b=b: np.sqrt(a**2 * np.sin(s) ** 2 + b**2 * np.cos(s) ** 2),
            0,
            2 * np.pi,
            epsabs=1e-12,
            epsrel=1e-12,
        )[0]
        assert quad == pytest.approx(c, rel=1e-10)
    # monotone interpolation: no overshoot between measurements
    for j in range(len(pos) - 1):
        seg = limb.circumference[at[j] : at[j + 1] + 1]
        d = np.diff(seg) * np.sign(circ[j + 1] - circ[j])
        assert (d >= -1e-9).all()
    assert limb.source == "measurements" and limb.notes == ()
    assert (turning(limb) < 0).all()
    assert np.allclose(limb.sections[:, 0, 1], 0) and (limb.sections[:, 0, 0] > 0).all()


def test_from_measurements_refuses_bad_input():
    """Measurements out of order, non-positive, mismatched or too close for the station spacing are refused
    with the key named."""
    cases = [
        (([0, 100, 90], [1, 2, 3]), {}, "positions_mm: must be strictly increasing"),
        (([0, 100], [160, -1]), {}, "circumferences_mm: must be > 0"),
        (([0, 100], [160]), {}, "circumferences_mm: needs one value per position"),
        (([0, 100], [160, 200]), {"ellipticity": 1.5}, "ellipticity: minor/major ratio must be in (0, 1]"),
        (([0, 100, 101], [160, 200, 201]), {"n_stations": 11}, "closer than the station spacing"),
        (([0, 100], [160, 200]), {"n_around": 4}, "n_around: must be an integer >= 8"),
    ]
    for args, kwargs, message in cases:
        with pytest.raises(ConfigError) as info:
            Limb.from_measurements(*args, **kwargs)
        assert message in str(info.value)
    ell = ellipse_semi_axes(100.0, 1.0)
    assert ell[0] == pytest.approx(100 / (2 * np.pi), rel=1e-15)


def test_example_arm_is_a_typical_adult_arm():
    """The example arm runs wrist to upper arm with the upper arm about twice the wrist and increasing
    positions."""
    arm = example_arm()
    c = arm.circumference
    assert arm.sections.shape == (41, 64, 3)
    assert (np.diff(arm.positions) > 0).all() and arm.positions[-1] == pytest.approx(420.0)
    assert 150 <= c[0] <= 170 and 260 <= c[-1] <= 340
    assert 1.8 <= c[-1] / c[0] <= 2.2
    assert arm.named_stations["largest"] == 40 and arm.named_stations["distal"] == 0
    assert np.allclose(
        c[np.searchsorted(arm.positions, [m[0] for m in EXAMPLE_ARM_MEASUREMENTS])],
        [m[1] for m in EXAMPLE_ARM_MEASUREMENTS],
        rtol=1e-10,
    )
    assert arm.source == "example"
    assert (arm.curvature_radius > 0).all()
    assert load_limb("example").circumference == pytest.approx(c)
    spec = {"positions_mm": [0, 300], "circumferences_mm": [160, 300], "n_stations": 5}
    assert load_limb(spec).circumference[[0, -1]] == pytest.approx([160, 300])


# ----------------------------------------------------------------------------------------------
# bad scans
# ----------------------------------------------------------------------------------------------


def test_empty_or_unreadable_files_are_refused(tmp_path):
    """A zero-byte file, random bytes, text in an .obj, a PLY named .stl, a missing file and a folder each
    give one line naming the file."""
    (tmp_path / "empty.stl").write_bytes(b"")
    raises_data_error(tmp_path / "empty.stl", "empty file (0 bytes)")
    (tmp_path / "noise.stl").write_bytes(np.random.default_rng(0).bytes(2000))
    raises_data_error(tmp_path / "noise.stl", "not a readable mesh")
    (tmp_path / "noise.ply").write_bytes(np.random.default_rng(1).bytes(2000))
    raises_data_error(tmp_path / "noise.ply", "not a readable mesh")
    (tmp_path / "letter.obj").write_text("Dear fitter,\nplease find the arm attached.\n")
    raises_data_error(tmp_path / "letter.obj", "no mesh data found")
    trimesh.creation.cylinder(radius=R, height=H).export(str(tmp_path / "real.ply"))
    (tmp_path / "ply_named.stl").write_bytes((tmp_path / "real.ply").read_bytes())
    raises_data_error(tmp_path / "ply_named.stl", "not a readable mesh (.stl file)")
    raises_data_error(tmp_path / "missing.stl", "no such file")
    (tmp_path / "folder.stl").mkdir()
    raises_data_error(tmp_path / "folder.stl", "is a folder")


def test_point_clouds_without_triangles_are_refused(tmp_path):
    """A PLY point cloud and an OBJ of vertices only are refused: no triangles."""
    pts = np.random.default_rng(0).normal(size=(200, 3)) * [30, 30, 150]
    trimesh.PointCloud(pts).export(str(tmp_path / "cloud.ply"))
    raises_data_error(tmp_path / "cloud.ply", "no triangles: 200 points")
    (tmp_path / "cloud.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y, z in pts))
    raises_data_error(tmp_path / "cloud.obj", "no triangles")


def test_non_finite_coordinates_are_refused(tmp_path):
    """A vertex with NaN (OBJ) or infinity (binary STL) coordinates is refused."""
    mesh = trimesh.creation.cylinder(radius=R, height=H, sections=32)
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in mesh.vertices]
    lines[3] = "v nan 0.0 1.0"
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces]
    (tmp_path / "nan.obj").write_text("\n".join(lines) + "\n")
    raises_data_error(tmp_path / "nan.obj", "non-finite coordinates")
    bad = mesh.copy()
    bad.vertices[5] = [np.inf, 0.0, 0.0]
    with np.errstate(invalid="ignore"):  # the STL writer's face normals
        save(bad, tmp_path / "inf.stl")
    raises_data_error(tmp_path / "inf.stl", "non-finite coordinates")


def test_outer_shell_around_inner_shells_is_chosen_with_a_notice(tmp_path):
    """Skin around two bones (three shells, the outer enclosing both) gives the outer limb and says so; a
    small debris fragment is ignored with a notice."""
    skin = trimesh.creation.cylinder(radius=R, height=H, sections=128)
    bones = [
        trimesh.creation.cylinder(
            radius=9.0,
            height=H - 20,
            sections=32,
            transform=trimesh.transformations.translation_matrix([x, 5.0, 0]),
        )
        for x in (-20.0, 18.0)
    ]
    tf = rigid(2)
    scan = trimesh.util.concatenate([skin, *bones])
    scan.apply_transform(tf)
    limb = Limb.from_scan(save(scan, tmp_path / "arm_bones.stl"))
    assert limb.notes == ("outer shell of 3 chosen; 2 inner shells ignored",)
    assert np.abs(limb.circumference / (2 * np.pi * R) - 1).max() < 5e-3
    debris = trimesh.creation.icosphere(subdivisions=1, radius=2.0)
    debris.apply_translation([200.0, 0, 0])
    limb = Limb.from_scan(save(trimesh.util.concatenate([skin, debris]), tmp_path / "arm_debris.stl"))
    assert len(limb.notes) == 1 and limb.notes[0].startswith("1 small disconnected fragment")


def test_shells_side_by_side_are_refused_as_ambiguous(tmp_path):
    """Two arms side by side (two shells, neither inside the other) are refused as ambiguous."""
    a = trimesh.creation.cylinder(radius=R, height=H, sections=64)
    b = trimesh.creation.cylinder(
        radius=45.0,
        height=H,
        sections=64,
        transform=trimesh.transformations.translation_matrix([150.0, 0, 0]),
    )
    raises_data_error(
        save(trimesh.util.concatenate([a, b]), tmp_path / "two_arms.stl"), "2 separate shells side by side"
    )
    # one inside, one beside: still ambiguous
    c = trimesh.creation.cylinder(radius=10.0, height=H - 20, sections=32)
    raises_data_error(
        save(trimesh.util.concatenate([a, b, c]), tmp_path / "mixed.stl"),
        "3 separate shells side by side (1 not inside",
    )


@pytest.mark.parametrize(
    "shape, match",
    [
        ("sphere", "times its mean diameter"),
        ("cube", "times its mean diameter"),
        ("plate", "is flat"),
        ("sheet", "no cross-section is a closed loop"),
        ("pointed cone", "cross-section length varies"),
    ],
)
def test_non_tubular_scans_are_refused(tmp_path, shape, match):
    """A sphere, a cube, a thin plate, an open sheet and a cone to a point are refused as not tubular."""
    if shape == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=80.0)
    elif shape == "cube":
        mesh = trimesh.creation.box(extents=[150.0, 150.0, 150.0])
    elif shape == "plate":
        mesh = trimesh.creation.box(extents=[300.0, 200.0, 3.0])
    elif shape == "sheet":
        mesh = trimesh.Trimesh([[0, 0, 0], [300, 0, 0], [300, 200, 0], [0, 200, 0]], [[0, 1, 2], [0, 2, 3]])
        mesh = mesh.subdivide().subdivide().subdivide()
    else:
        mesh = trimesh.creation.cone(radius=50.0, height=300.0, sections=64)
    mesh.apply_transform(rigid(9))
    err = raises_data_error(save(mesh, tmp_path / "thing.stl"), match)
    assert "not tubular along its axis" in str(err)


def test_a_section_with_two_loops_is_refused_naming_the_station(tmp_path):
    """A ring stretched into a long loop (two tubes side by side, joined at the ends) is refused naming a
    station whose section has 2 loops."""
    ring = trimesh.creation.torus(major_radius=60.0, minor_radius=15.0, major_sections=96, minor_sections=24)
    ring.apply_scale([3.0, 1.0, 1.0])
    err = raises_data_error(save(ring, tmp_path / "ring.stl"), "section has 2 loops")
    assert "station " in str(err) and " mm: section has 2 loops" in str(err)


def test_a_torn_section_is_refused_unless_in_the_trimmed_ends(tmp_path):
    """A hole through the wall is refused naming its station, but not when it lies in the trimmed end."""
    mesh = trimesh.creation.capsule(height=300.0, radius=40.0, count=[48, 48])
    centres = mesh.triangles_center
    z_tip = mesh.vertices[:, 2].min()
    hole = (np.abs(centres[:, 2] - (z_tip + 15.0)) < 6.0) & (centres[:, 0] > 25.0)
    mesh.update_faces(~hole)
    path = save(mesh, tmp_path / "torn.stl")
    limb = Limb.from_scan(path, trim=0.08)  # the hole is within the 30 mm trimmed end
    assert limb.n_stations == 41
    err = raises_data_error(path, "section is not closed", trim=0.02)
    text = str(err)
    station = int(text.split("station ")[1].split(" ")[0])
    position = float(text.split(" at ")[1].split(" mm")[0])
    assert 0 <= station <= 3 and position < 15.0


def test_a_100k_triangle_scan_loads_quickly(tmp_path):
    """A 100 000-triangle capsule loads and slices into 41 x 64 stations (time printed, not asserted)."""
    mesh = trimesh.creation.capsule(height=400.0, radius=45.0, count=[224, 224])
    assert len(mesh.faces) >= 100_000
    mesh.apply_transform(rigid(4))
    path = save(mesh, tmp_path / "big.stl")
    start = time.perf_counter()
    limb = Limb.from_scan(path)
    elapsed = time.perf_counter() - start
    print(f"\n{len(mesh.faces)}-triangle scan: read, sliced and resampled in {elapsed:.2f} s")
    middle = limb.circumference[10:31]
    assert np.abs(middle / (2 * np.pi * 45.0) - 1).max() < 5e-3
    assert limb.positions[-1] == pytest.approx(0.9 * (400.0 + 90.0), rel=1e-5)
