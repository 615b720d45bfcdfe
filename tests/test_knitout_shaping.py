"""Machine output of a shaped tube: increases and decreases at the tube's edges, checked course by course
in knitout-interpreter's knit graph; an unshaped tube's program is unchanged; the stitch-number note; the
chart."""

from __future__ import annotations

import hashlib
import json
import types
from collections import defaultdict

import numpy as np
import pytest
from hostile.conftest import assert_refused, knit_here, snapshot  # noqa: F401 (knit_here is a fixture)
from test_knitout import check_knitted, write_design

from knitframe.garment.knitout import (
    Band,
    KnitMap,
    MachineOutputError,
    MachineSpec,
    chart_figure,
    knitout_lines,
    plan,
    verify,
)

#: 13 stitches cast on; increases of 1, 2 and 2, then decreases of 1, 2 and 2 and an increase of 1,
#: every second course (the default machine rules)
COUNTS = [13, 13, 14, 14, 16, 16, 18, 18, 17, 17, 15, 15, 13, 13, 14, 14]
#: three stripes: the yarn changes between two shaping courses (course 5) and on one (course 10, a carrier
#: brought in)
STRIPES = [(0, 5, "a"), (5, 10, "b"), (10, 16, "c")]


def shaped_map(pattern: str, counts=COUNTS) -> KnitMap:
    bands = [Band(s, e, f"{y}-{pattern}", pattern, y, 11) for s, e, y in STRIPES]
    return KnitMap(counts[0], bands, course_needles=counts)


def shaped_folder(folder, counts, bands=((16, "a-j", "jersey", "a", 11),)):
    """A design folder (test_knitout.write_design) whose design.json gives ``counts`` as
    tube.needles_per_course."""
    write_design(folder, 13, list(bands))
    data = json.loads((folder / "design.json").read_text())
    data["tube"]["needles_per_course"] = counts
    (folder / "design.json").write_text(json.dumps(data))
    return folder


def simulate(lines: list[str]) -> list[dict[int, tuple[bool, bool]]]:
    """Run the program on a model of the two beds (loops per needle, the racking) independently of
    knitout-interpreter, checking at every step that a transfer joins two aligned needles, that the needle
    opposite a stitch being knitted is empty and that no needle holds more than three loops. Returns each
    course's stitches (knits and tucks after the cast-on, up to the bind-off): needle -> (front bed, tuck)."""
    loops: dict[tuple[str, int], int] = defaultdict(int)
    rack, courses, last = 0, [], None
    for s in lines:
        if s.startswith("; bind-off"):
            break
        op = s.split()
        if op[0] == "rack":
            rack = int(op[1])
        elif op[0] == "xfer":
            (a, n), (b, m) = (op[1][0], int(op[1][1:])), (op[2][0], int(op[2][1:]))
            assert a != b and (n - m if a == "f" else m - n) == rack, (s, rack)
            assert loops[(a, n)] > 0, s
            loops[(b, m)] += loops.pop((a, n))
            assert loops[(b, m)] <= 3, s
        elif op[0] in ("knit", "tuck"):
            bed, n = op[2][0], int(op[2][1:])
            assert loops[("b" if bed == "f" else "f", n)] == 0, f"{s}: the needle opposite holds a loop"
            assert (loops[(bed, n)] == 0) == (op[0] == "tuck"), s
            loops[(bed, n)] = 1
            if op[0] == "knit" or courses:  # the cast-on is tucks only
                if not courses or (op[1] == "-" and last == "+"):  # a course begins with the front layer
                    courses.append({})
                courses[-1][n] = (bed == "f", op[0] == "tuck")
            last = op[1]
    return courses


def reverse_by_needle(course) -> dict[int, bool]:
    """Seen from outside the tube, which knitted stitches of a knit-graph course are purls, by needle.

    The course begins at its rightmost stitch, on the front layer, and the layers alternate needle by needle:
    a plain stitch is pulled back-to-front on the front layer and front-to-back on the back."""
    from knit_graphs.Pull_Direction import Pull_Direction

    right = course[0].source_needle.position
    return {
        loop.source_needle.position: (loop.pull_direction is Pull_Direction.BtF)
        != ((right - loop.source_needle.position) % 2 == 0)
        for loop in course
        if loop.parent_loops  # a tuck (a new stitch) has none
    }


def test_counts_follow_the_machine_rules():
    """The test tube is one the design could make under the default machine rules: shaping courses two
    apart, each changing by 1 or 2 stitches, both ways."""
    shaping = [c for c in range(1, len(COUNTS)) if COUNTS[c] != COUNTS[c - 1]]
    assert (
        shaping
        == list(range(2, 16, 2))
        == KnitMap(13, [Band(0, 16, "a", "jersey", "a")], "", COUNTS).shaping_courses
    )
    assert {COUNTS[c] - COUNTS[c - 1] for c in shaping} == {1, 2, -1, -2}


@pytest.mark.parametrize("pattern", ["jersey", "rib", "garter", "seed"])
def test_shaped_tube_knits_every_course_with_its_stitches(pattern):
    """knitout-interpreter runs the program with no error, warning or violation, and its knit graph has each
    course's number of loops (the check that verify() makes, and an independent one); every course fills its
    needles from edge to edge, one stitch each with the needle opposite empty; the pattern holds through the
    changes."""
    p = plan(shaped_map(pattern), MachineSpec())
    lines = knitout_lines(p)
    report = verify(p, lines)
    assert report["shaping_courses"] == 7 and report["stitches_range"] == [13, 18]
    bands = [(b.start, b.end, b.pattern, b.yarn) for b in p.kmap.bands]
    graph = check_knitted(lines, COUNTS, bands, p.carriers)
    assert [len(c) for c in graph] == COUNTS
    stitches = simulate(lines)
    assert [len(c) for c in stitches] == COUNTS
    assert len({max(course) % 2 for course in stitches}) == 1  # the rightmost stitch stays on the front layer
    for c, course in enumerate(stitches):
        needles = sorted(course)
        assert needles == list(range(needles[0], needles[-1] + 1)), c  # one stitch on every needle
        assert sum(t for _, t in course.values()) == max(0, COUNTS[c] - COUNTS[c - 1]) * (c > 0), c
    assert [s for s in lines if s.startswith("; course ")] == [
        "; course 2: increase from 13 to 14 stitches (1 at the left)",
        "; course 4: increase from 14 to 16 stitches (2 at the right)",
        "; course 6: increase from 16 to 18 stitches (2 at the left)",
        "; course 8: decrease from 18 to 17 stitches (1 at the left)",
        "; course 10: decrease from 17 to 15 stitches (2 at the left)",
        "; course 12: decrease from 15 to 13 stitches (2 at the right)",
        "; course 14: increase from 13 to 14 stitches (1 at the left)",
    ]
    rev = [reverse_by_needle(c) for c in graph]
    for c, r in enumerate(rev):
        band = next(b for b in p.kmap.bands if b.start <= c < b.end)
        k = c - band.start
        along = [(r[n], r[n + 2]) for n in r if n + 2 in r]  # neighbours in one layer
        if pattern == "jersey":
            assert not any(r.values()), c
        if pattern == "garter":
            assert set(r.values()) == {k % 2 == 1}, c
        if pattern in ("rib", "seed"):
            assert all(a != b for a, b in along), c  # alternates along each layer
        if c and k and pattern in ("rib", "seed"):  # up each needle: rib stays, seed flips
            up = [r[n] == rev[c - 1][n] for n in r if n in rev[c - 1]]
            assert set(up) == {pattern == "rib"}, c


def test_the_check_refuses_a_program_whose_courses_do_not_have_the_design_stitches():
    """verify() compares every course of the knit graph with the map: a program knitted for other counts
    fails, naming the first course that differs."""
    p = plan(shaped_map("jersey"), MachineSpec())
    other = plan(shaped_map("jersey", COUNTS[:8] + [18] * 8), MachineSpec())
    with pytest.raises(
        MachineOutputError, match=r"courses have the wrong number of loops \(course 8: 17, not 18\)"
    ):
        verify(other, knitout_lines(p))


UNSHAPED = KnitMap(
    10,
    [
        Band(0, 3, "j", "jersey", "a", 11),
        Band(3, 7, "r", "rib", "a", 12),
        Band(7, 11, "g", "garter", "a", 10),
        Band(11, 15, "s", "seed", "a", 11),
    ],
)
ODD_TWO_YARNS = KnitMap(
    11,
    [
        Band(0, 2, "a-j", "jersey", "a"),
        Band(2, 5, "b-s", "seed", "b"),
        Band(5, 13, "a-r", "rib", "a"),
        Band(13, 15, "b-g", "garter", "b"),
    ],
)


def sha(lines: list[str]) -> str:
    return hashlib.sha256(("\n".join(lines) + "\n").encode()).hexdigest()


def test_an_unshaped_tube_gives_the_same_program_as_before_shaping():
    """The program of a tube with one count for every course is byte for byte the one written before
    shaping existed (hashes taken then); fabrics without a stitch length add only the one header note."""
    assert sha(knitout_lines(plan(UNSHAPED, MachineSpec()))) == (
        "32929c0441747f03d96915afdfba9b44129f4f1d8b46fc8c2e8feb2296aeda12"
    )
    lines = knitout_lines(plan(ODD_TWO_YARNS, MachineSpec()))
    note = (
        "; fabrics a-j, b-s, a-r, b-g have no stitch length: x-stitch-number 5 is the table's default; "
        "calibrate it"
    )
    assert lines.count(note) == 1
    assert (
        sha([s for s in lines if s != note])
        == "ca6c53aba99857b72dd61466bc1c94db8d77d503893de386d02687370aca3d9c"
    )


def test_knit_map_takes_the_stitches_of_every_course_from_the_design_or_its_folder(tmp_path):
    """from_design uses the design's needles_per_course() (a constant count without it, or when it gives
    None); read() uses design.json's tube.needles_per_course, else the constant count."""
    entry = types.SimpleNamespace(name="cotton-jersey", pattern="jersey", yarn="cotton", stitch_length=None)
    design = types.SimpleNamespace(
        tube=types.SimpleNamespace(mode="knitting", needles=13),
        courses=np.array([4.0, 4.0, 8.0]),
        fabric=np.zeros((3, 2), dtype=int),
        library=types.SimpleNamespace(entries=[entry]),
    )
    assert KnitMap.from_design(design).course_needles == (13,) * 16
    design.needles_per_course = lambda: None
    assert not KnitMap.from_design(design).shaped
    design.needles_per_course = lambda: np.array(COUNTS)
    kmap = KnitMap.from_design(design)
    assert (
        kmap.course_needles == tuple(COUNTS)
        and kmap.needles == 13
        and kmap.shaping_courses == [2, 4, 6, 8, 10, 12, 14]
    )
    stripes = [(5, "a-j", "jersey", "a", 11), (11, "b-j", "jersey", "b", 11)]
    folder = write_design(tmp_path / "d", 13, stripes)
    assert KnitMap.read(folder).course_needles == (13,) * 16
    shaped = KnitMap.read(shaped_folder(tmp_path / "s", COUNTS, stripes))
    assert shaped.course_needles == tuple(COUNTS) and [b.yarn for b in shaped.bands] == ["a", "b"]


BAD = [
    ("too-few-entries", COUNTS[:-1], "has 15 entries for 16 courses"),
    ("too-few-stitches", [13, 13, 11, 9, 7, 5, 3] + [3] * 9, "gives course 6 3 stitches"),
    ("not-integers", [13.5] * 16, "must be a list of integers"),
    ("not-a-list", 13, "must be a list of integers"),
    ("not-the-cast-on", [14] * 16, "starts at 14 stitches but the tube casts on 13"),
]


@pytest.mark.parametrize("case, counts, problem", BAD, ids=[c[0] for c in BAD])
def test_bad_stitches_per_course_are_refused_in_one_line(tmp_path, knit_here, case, counts, problem):  # noqa: F811
    """A needles_per_course that does not fit the knit map is refused in one line naming the field."""
    shaped_folder(tmp_path / "d", counts)
    before = snapshot(tmp_path)
    proc = knit_here("knitout", "d", "--out", "out", "--no-check", cwd=tmp_path)
    assert_refused(proc, "tube.needles_per_course", before=before, folder=tmp_path)
    assert problem in proc.stderr


@pytest.mark.parametrize(
    "counts, args, field",
    [([13] * 8 + [23] * 8, [], "needles_per_course"), (COUNTS, ["--width", "16"], "--width")],
    ids=["change-too-large", "wider-than-the-machine"],
)
def test_what_the_machine_cannot_shape_is_refused(tmp_path, knit_here, counts, args, field):  # noqa: F811
    """A course changing more stitches than the transfers can make, or a shaped tube whose courses span
    more needles than the machine's width, is refused in one line."""
    shaped_folder(tmp_path / "d", counts)
    before = snapshot(tmp_path)
    proc = knit_here("knitout", "d", "--out", "out", "--no-check", *args, cwd=tmp_path)
    assert_refused(proc, field, before=before, folder=tmp_path)


def test_a_fabric_without_stitch_length_is_noted_in_one_line(tmp_path, knit_here):  # noqa: F811
    """Where the library gives no stitch length, the program's header, the summary's notes and the command
    say in one line that the stitch number is the table's default; a fabric with one gets no note."""
    write_design(tmp_path / "d", 12, [(3, "acrylic-rib", "rib", "a", None), (3, "c-j", "jersey", "c", 11)])
    proc = knit_here("knitout", "d", "--out", "out", "--no-check", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    note = "fabric acrylic-rib has no stitch length: x-stitch-number 5 is the table's default; calibrate it"
    lines = (tmp_path / "out" / "sleeve.k").read_text().splitlines()
    assert [s for s in lines if "no stitch length" in s] == [f"; {note}"]
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["notes"] == [note]
    assert [s for s in proc.stdout.splitlines() if "no stitch length" in s] == [f"note: {note}"]
    assert plan(UNSHAPED, MachineSpec()).notes == []


def test_the_chart_follows_the_stitches_of_every_course_and_its_labels_do_not_overlap():
    """The chart fills each course's needles only (the outline follows the count), marks each shaping course,
    shows the stitches of every course beside it, and no two of its labels overlap."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = plan(shaped_map("seed"), MachineSpec())
    fig = chart_figure(p)
    try:
        fig.canvas.draw()
        chart = fig.axes[0]
        mesh = chart.collections[0]
        assert (~np.ma.getmaskarray(mesh.get_array())).sum() == sum(COUNTS)
        marks = [ln for ln in chart.lines if ln.get_marker() in ("^", "v")]
        assert len(marks) == 7  # one edge changes on each shaping course here
        assert list(fig.axes[1].patches[0].get_data().values) == COUNTS  # the stitches panel
        renderer = fig.canvas.get_renderer()
        texts = [
            t
            for t in fig.findobj(matplotlib.text.Text)
            if t.get_visible() and t.get_text().strip() and t.get_window_extent(renderer).width > 0
        ]
        boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in texts]
        overlaps = [
            (a, b)
            for i, (a, box) in enumerate(boxes)
            for b, other in boxes[i + 1 :]
            if box.overlaps(other) and box != other
        ]
        assert not overlaps, overlaps[:3]
    finally:
        plt.close(fig)
