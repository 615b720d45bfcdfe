r"""Machine output for a designed sleeve: a knitout program for a V-bed machine, its chart and a DAT file.

A knitting-mode design (:class:`~knitframe.garment.core.Design`, or its ``design.json`` and
``knit-map.csv``) is a tube of N stitches per course whose regions are course bands (stripes), each
knitted in one fabric: a pattern, a yarn and a stitch length. :class:`KnitMap` holds exactly that;
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
stitches takes N needles of each bed (``width`` ≥ N). The fabric's gauge is half the machine's.

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
them there.

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
cast-on's N loops, then each course of the map with N loops, each band in its carrier, and no loop
left on the needles. knitout-to-dat-python 0.0.4 imports names that knitout-interpreter moved after
0.1.2 (``knitframe[dat]`` pins that set) and ignores ``x-stitch-number``; :func:`write_dat` gives its
passes the stitch numbers itself.

Units: mm (stitch lengths are machine settings, as in the fabric library).

Modules: :mod:`.knitmap` (the knit map), :mod:`.machine` (machine settings and the plan),
:mod:`.writer` (the program), :mod:`.checking` (knitout-interpreter and the DAT file),
:mod:`.chart` (the stitch chart) and :mod:`.outputs` (the files).
"""

from knitframe.garment.knitout.chart import plot_chart, transfers_before
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
    wales,
)

__all__ = [
    "Band",
    "KnitMap",
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
    "FIRST_NEEDLE",
    "TAIL",
    "POSITION",
    "FILES",
    "INSTALL",
    "INSTALL_DAT",
]
