r"""Machine output for a designed sleeve: a knitout program for a V-bed machine, its chart and a DAT file.

A knitting-mode design (:class:`~knitframe.garment.core.Design`, or its ``design.json`` and
``knit-map.csv``) is a tube whose regions are course bands (stripes), each knitted in one fabric: a
pattern, a yarn and a stitch length. It casts on N stitches and may be shaped: course c knits
``course_needles[c]`` stitches. :class:`KnitMap` holds exactly that;
:func:`plan` resolves the machine settings of every band (:class:`MachineSpec`: carrier, stitch
number) and refuses, in one line, what the machine cannot knit; :func:`knitout_lines` writes the
`knitout <https://textiles-lab.github.io/knitout/knitout.html>`_ program, :func:`plot_chart` its
stitch chart, :func:`verify` runs it through ``knitout-interpreter`` (a simulated Shima SWG091N2) and
checks the knit graph it makes, and :func:`write_dat` converts it to a Shima DAT file through
``knitout-to-dat-python``.

Conventions
-----------
**Needles (half gauge).** The tube is knitted in the round on both beds at half gauge. Needle
positions p = 0 … N−1 (knitout needle ``FIRST_NEEDLE + p``) hold one stitch each, alternately of
the two layers, the rightmost of the front layer (:func:`front_layer`):

- p = N−1, N−3, …: the tube's front layer (⌈N/2⌉ stitches), at home on the front bed;
- p = N−2, N−4, …: the back layer (⌊N/2⌋ stitches), at home on the back bed.

A carrier brought in starts on the rightmost stitch, so the yarn-inserting hook, parked just right
of it until ``releasehook``, blocks no needle of the tube. The needle opposite every stitch is
empty, so any stitch can be turned into a purl by moving its loop across (``xfer`` at rack 0) and
knitting it on the other bed; that is how rib, garter and seed are knitted in a tube. A tube of N
stitches takes N needles of each bed (``width`` ≥ N; a shaped tube the span of its courses, see
below). The fabric's gauge is half the machine's.

**Courses.** One course is one round: the front layer leftward (``knit -``, from the right), then the
back layer rightward (``knit +``), a spiral with the yarn passing from the front to the back at the
left edge and from the back to the front at the right edge. Before a course, the loops whose bed
changes are transferred (front to back first, then back to front).

**Wales and patterns.** Around the tube, wale w runs along the front layer from its left edge
(w = j for its j-th stitch from the left) and back along the back layer (w = N − 1 − k for its
k-th). Seen from outside, a stitch is plain (knit on its home bed) or reverse (purl, knit on the
other bed). Course c counts from the start of its band:

=========  ========================  =========================================
pattern    reverse stitches           needs
=========  ========================  =========================================
jersey     none                       nothing
rib        odd wales (1×1)            purls on the opposite bed (no transfers)
garter     odd courses                a transfer of every loop between courses
seed       odd w + c                  a transfer of every loop between courses
=========  ========================  =========================================

With an odd N, the rib and seed meet themselves out of step once around the tube (two plain or two
reverse wales side by side at its left edge, w = N − 1 next to w = 0). Any other pattern is refused,
and so is a course that changes fabric along its length: intarsia cannot be knitted in the round.

**Shaping.** A shaped tube changes its stitches on *shaping courses* (the courses whose count
differs from the course below's; :mod:`knitframe.garment.shaping` schedules them under the
machine's rules), at the tube's two edges, by transfers made just before the course
(:class:`Layout`, :func:`tube_layout`):

- the layout keeps its parity: the front layer stays on the needles of one parity and the back layer
  on the others, and every course's stitches fill the needles from its left edge to its right edge,
  one stitch each, so every stitch keeps the empty needle opposite it (patterns still transfer
  across). The rightmost stitch stays on the front layer (where a carrier brought in starts), so the
  right edge moves by pairs (one stitch of each layer) and the left edge by one or two; each change
  is split between the edges to keep the tube where it was cast on (a change of 2 alternates
  between the edges, an odd stitch goes to the left). Positions count from the leftmost needle any
  course uses.
- a **decrease** stacks each stitch leaving the tube onto its layer's next stitch inward (two
  needles along): ``xfer`` to the empty needle opposite, ``rack ±2``, ``xfer`` onto the stitch (one
  ``xfer`` when the two loops are on different beds), then ``rack 0``; the course knits both loops
  together.
- an **increase** moves each layer's edge stitch out to the layer's new edge the same way, leaving
  its needle empty just inside the edge, and the course **tucks** that empty needle (a tuck on an
  empty needle, as in the cast-on, which knitout-interpreter accepts without a warning: an eyelet
  one stitch in from the edge); the next course knits the tuck.
- at most :data:`MAX_COURSE_CHANGE` stitches change on one course (four at each edge: a stitch
  moves at most four needles, the SWG091N2's largest racking, and a needle holds at most three
  loops).
- wales and patterns belong to the needles: a stitch's wale is counted from the cast-on course's
  layout, so a change leaves every other stitch on its bed; a new stitch and a stitch moved out
  take the pattern of their new needle. Rib and seed may meet out of step at either edge.

**Carriers.** One carrier per yarn: ``carriers`` maps yarn → carrier number, and yarns it does not
name take the lowest free carriers in the order the tube first uses them. A stripe changes carrier
between courses. A carrier brought in uses the yarn-inserting hook (``inhook``, released with
``releasehook`` after its first course); a yarn that is not used again within
:data:`CARRY_COURSES` courses is cut (``outhook``) after its last course, otherwise it is carried up
inside the tube. The SWG091N2 has 10 carriers; more yarns are refused.

**Stitch numbers.** ``x-stitch-number N`` (an index, 1–120, into the machine's stitch table) is set
for each band from its fabric's stitch length through a table keyed by the machine setting (``"11"``)
with a ``"default"`` for fabrics without one: :data:`DEFAULT_STITCH_NUMBERS`, overridden key by key
by the user's table. The numbers are indices into the stitch table set up on your machine; calibrate
them there. Where the library gives a fabric no stitch length, :attr:`Plan.notes` says so in one
line (the program's header, ``write_machine_outputs``' ``notes`` and the command print it).

**Cast-on and bind-off.** The first band's carrier casts on with alternating tucks (every other
stitch of the front layer leftward, of the back layer rightward, then the others), each on the bed
its first course needs. The last band's carrier binds off in a chain around the tube: every loop is
knitted, then moved onto the next stitch's needle (through the empty needle opposite and at rack −2
along a layer; directly at rack ±1 from the front layer's left stitch to the back layer's) and
knitted with it. The last loop is knitted :data:`TAIL` more times, the yarn is cut and the loop
dropped.

**Checking and DAT.** :func:`verify` runs :func:`interpreter_text` of the program: knitout-interpreter
0.1's grammar has neither the ``;;Width:`` header nor ``x-`` extensions, so exactly those lines
become comments (line numbers kept). It fails on any error, machine-state violation or warning
(a knit on an empty needle, a dropped loop, a long float …) and checks the knit graph: the
cast-on's N loops, then each course of the map with its own number of loops (``course_needles``),
each band in its carrier, and no loop left on the needles. knitout-to-dat-python 0.0.4 imports
names that knitout-interpreter moved after 0.1.2 (``knitframe[dat]`` pins that set) and ignores
``x-stitch-number``; :func:`write_dat` gives its passes the stitch numbers itself.

Units: mm (stitch lengths are machine settings, as in the fabric library).

Modules: :mod:`.knitmap` (the knit map), :mod:`.layout` (the needles of every course and the
shaping moves), :mod:`.machine` (machine settings and the plan),
:mod:`.writer` (the program), :mod:`.checking` (knitout-interpreter and the DAT file),
:mod:`.chart` (the stitch chart) and :mod:`.outputs` (the files).
"""

from knitframe.garment.knitout.chart import chart_figure, plot_chart
from knitframe.garment.knitout.checking import (
    INSTALL,
    INSTALL_DAT,
    MachineOutputError,
    interpreter_text,
    missing,
    run_interpreter,
    stitch_numbers_by_line,
    verify,
    write_dat,
)
from knitframe.garment.knitout.knitmap import PAPER_MODE, Band, KnitMap
from knitframe.garment.knitout.layout import MAX_COURSE_CHANGE, Layout, tube_layout
from knitframe.garment.knitout.machine import (
    DEFAULT_GAUGE,
    DEFAULT_MACHINE,
    DEFAULT_STITCH_NUMBERS,
    MACHINES,
    PATTERNS,
    STITCH_NUMBER_RANGE,
    MachineSpec,
    Plan,
    check_patterns,
    plan,
)
from knitframe.garment.knitout.outputs import program, write_machine_outputs
from knitframe.garment.knitout.writer import (
    CARRY_COURSES,
    FILES,
    FIRST_NEEDLE,
    POSITION,
    TAIL,
    front_bed,
    front_layer,
    knitout_lines,
    purl_mask,
    transfers_before,
    wales,
)

__all__ = [
    "Band",
    "KnitMap",
    "Layout",
    "tube_layout",
    "MachineSpec",
    "Plan",
    "MachineOutputError",
    "plan",
    "check_patterns",
    "purl_mask",
    "front_layer",
    "front_bed",
    "wales",
    "knitout_lines",
    "interpreter_text",
    "run_interpreter",
    "verify",
    "write_dat",
    "plot_chart",
    "chart_figure",
    "transfers_before",
    "program",
    "write_machine_outputs",
    "missing",
    "stitch_numbers_by_line",
    "MACHINES",
    "PAPER_MODE",
    "DEFAULT_MACHINE",
    "DEFAULT_GAUGE",
    "DEFAULT_STITCH_NUMBERS",
    "STITCH_NUMBER_RANGE",
    "PATTERNS",
    "CARRY_COURSES",
    "MAX_COURSE_CHANGE",
    "FIRST_NEEDLE",
    "TAIL",
    "POSITION",
    "FILES",
    "INSTALL",
    "INSTALL_DAT",
]
