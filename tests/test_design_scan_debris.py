"""Scans as scanners write them: stray triangles, slivers and small blobs beside the limb, bones inside it."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from test_design_limb import raises_data_error, rigid, save

from knitframe.errors import KnitframeWarning
from knitframe.garment.limb import Limb
from knitframe.garment.limb.shells import FRAGMENT_AREA_FRACTION

LENGTH = 400.0  # the arm's cylindrical part; its domed ends add a radius each


def arm() -> trimesh.Trimesh:
    """A closed arm in mm along z: a capsule tapered from 28 mm (wrist) to 48 mm radius (upper arm)."""
    mesh = trimesh.creation.capsule(height=LENGTH, radius=40.0, count=[48, 48])
    v = mesh.vertices.copy()
    t = (v[:, 2] - v[:, 2].min()) / np.ptp(v[:, 2])
    v[:, :2] *= (0.7 + 0.5 * t)[:, None]
    return trimesh.Trimesh(v, mesh.faces, process=False)


def triangle(*corners) -> trimesh.Trimesh:
    return trimesh.Trimesh(np.array(corners, dtype=np.float64), [[0, 1, 2]], process=False)


def sliver() -> trimesh.Trimesh:
    """A stray triangle 440 mm long and 8 mm wide beside the arm, above 1 % of its area."""
    return triangle([90.0, 0.0, -220.0], [90.0, 0.0, 220.0], [98.0, 0.0, 0.0])


def debris() -> list[trimesh.Trimesh]:
    """Four single stray triangles (one a long sliver, one inside the arm) and a 3 mm blob of 320."""
    blob = trimesh.creation.icosphere(subdivisions=2, radius=3.0)
    blob.apply_translation([0.0, 110.0, 50.0])
    return [
        triangle([60.0, 0.0, 0.0], [62.0, 0.0, 0.0], [60.0, 1.5, 0.0]),  # just off the skin
        triangle([900.0, 300.0, 0.0], [903.0, 300.0, 0.0], [900.0, 303.0, 1.0]),  # far away
        triangle([0.0, 0.0, 10.0], [4.0, 0.0, 10.0], [0.0, 4.0, 12.0]),  # inside the arm
        sliver(),
        blob,
    ]


def scan_with_debris(tmp_path, name="arm_debris.stl", scale=1.0) -> str:
    """The arm with its debris, turned and moved (a scanner's own frame), scaled by ``scale``."""
    mesh = trimesh.util.concatenate([arm(), *debris()])
    mesh.apply_transform(rigid(12))
    mesh.apply_scale(scale)
    return save(mesh, tmp_path / name)


def debris_note(limb: Limb) -> str:
    (note,) = [n for n in limb.notes if "dropped as scan debris" in n]
    return note


def test_stray_triangles_a_sliver_and_a_blob_are_dropped_with_one_notice(tmp_path):
    """Four stray triangles (one a sliver over 1 % of the arm's area) and a small blob are dropped, with one
    notice giving their count, triangles, area share and largest size, and the arm is the clean arm."""
    assert sliver().area > FRAGMENT_AREA_FRACTION * arm().area  # area alone would not call it debris
    clean = arm()
    clean.apply_transform(rigid(12))
    expected = Limb.from_scan(save(clean, tmp_path / "arm.stl"))
    limb = Limb.from_scan(scan_with_debris(tmp_path))
    note = debris_note(limb)
    print(f"\n{note}")
    assert limb.notes == (note,) and "\n" not in note
    assert note.startswith("5 small disconnected fragments dropped as scan debris (1–320 triangles each, ")
    share = float(note.split("at most ")[1].split(" %")[0])
    assert share == pytest.approx(100 * sliver().area / arm().area, rel=0.05)
    across = float(note.split("the largest ")[1].split(" mm across")[0])
    assert 440.0 / np.sqrt(3) <= across <= 440.0 * (1 + 1e-9)  # the sliver, within its box's bound
    assert np.allclose(limb.sections, expected.sections, atol=1e-6)
    assert np.allclose(limb.circumference, expected.circumference, rtol=1e-9)


def test_one_fragment_is_described_alone(tmp_path):
    """A single stray triangle is reported as one fragment: one triangle, its area share and its size (here
    its hypotenuse, 3√2 mm)."""
    mesh = trimesh.util.concatenate([arm(), triangle([0, 120, 0], [3, 120, 0], [0, 123, 0])])
    limb = Limb.from_scan(save(mesh, tmp_path / "arm_one.stl"))
    print(f"\n{limb.notes[0]}")
    assert limb.notes == (
        "1 small disconnected fragment dropped as scan debris "
        "(1 triangle, under 0.01 % of the limb's area, 4.2 mm across)",
    )


def test_a_finely_meshed_clump_is_dropped_by_its_size(tmp_path):
    """A 22 mm clump beside the arm is dropped by its size, though its area is over 1 % of the arm's and it
    has 1280 triangles."""
    clump = trimesh.creation.icosphere(subdivisions=3, radius=11.0)
    clump.apply_translation([0.0, 120.0, 0.0])
    assert clump.area > FRAGMENT_AREA_FRACTION * arm().area and len(clump.faces) == 1280
    limb = Limb.from_scan(save(trimesh.util.concatenate([arm(), clump]), tmp_path / "arm_clump.stl"))
    print(f"\n{limb.notes[0]}")
    assert limb.notes == (
        "1 small disconnected fragment dropped as scan debris "
        "(1280 triangles, 1.3 % of the limb's area, 22 mm across)",
    )


def test_bones_inside_are_ignored_and_debris_dropped(tmp_path):
    """A bone inside the arm is ignored with the inner-shell notice, and the debris beside it is dropped with
    its own notice."""
    bone = trimesh.creation.cylinder(radius=10.0, height=300.0, sections=48)
    bone.apply_translation([5.0, 0.0, 20.0])
    mesh = trimesh.util.concatenate([arm(), bone, *debris()])
    mesh.apply_transform(rigid(13))
    limb = Limb.from_scan(save(mesh, tmp_path / "arm_bone.stl"))
    print(f"\n{limb.notes}")
    assert len(limb.notes) == 2
    assert limb.notes[0] == "outer shell of 2 chosen; 1 inner shell ignored"
    assert limb.notes[1].startswith("5 small disconnected fragments dropped as scan debris (")
    clean = arm()
    clean.apply_transform(rigid(13))
    expected = Limb.from_scan(save(clean, tmp_path / "arm.stl"))
    assert np.allclose(limb.circumference, expected.circumference, rtol=1e-9)


def test_two_arms_side_by_side_with_debris_are_still_refused(tmp_path):
    """Two arms side by side are refused in one line as ambiguous, the debris around them not counted as
    shells."""
    other = arm()
    other.apply_translation([150.0, 0.0, 0.0])
    mesh = trimesh.util.concatenate([arm(), other, *debris()])
    mesh.apply_transform(rigid(14))
    err = raises_data_error(save(mesh, tmp_path / "two_arms.stl"), "2 separate shells side by side")
    print(f"\n{err}")
    assert "(1 not inside the largest): ambiguous which is the limb" in str(err)


def test_a_scan_in_metres_with_debris_is_converted_and_reports_mm(tmp_path):
    """The same scan in metres is converted to mm with its notice and warning, drops the same debris and
    reports its sizes in mm, as for the scan in mm."""
    in_mm = Limb.from_scan(scan_with_debris(tmp_path))
    with pytest.warns(KnitframeWarning, match="converted from metres"):
        limb = Limb.from_scan(scan_with_debris(tmp_path, "arm_debris_m.stl", scale=1e-3))
    print(f"\n{limb.notes}")
    assert len(limb.notes) == 2 and limb.notes[0].startswith("converted from metres")
    assert debris_note(limb) == debris_note(in_mm)
    assert np.allclose(limb.sections, in_mm.sections, rtol=0, atol=1e-6 * LENGTH)


def test_design_command_goes_through_a_scan_with_debris(tmp_path, cli):
    """`knitframe design arm.stl` on the scan with debris exits 0, and design.json carries the debris
    notice."""
    path = scan_with_debris(tmp_path, "arm.stl")
    proc = cli("design", path, "--out", "out", cwd=tmp_path)
    print(f"\n{proc.stdout}{proc.stderr}")
    assert proc.returncode == 0, proc.stderr
    design = json.loads((tmp_path / "out" / "design.json").read_text())
    (note,) = [n for n in design["limb"]["notes"] if "dropped as scan debris" in n]
    assert note.startswith("5 small disconnected fragments") and note in design["notes"]
