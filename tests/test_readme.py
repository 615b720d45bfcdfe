"""The README works as written: its bash and python blocks run in order from a copy of the repository root,
with the venv's programs, and every number it quotes is what the code (or the page that records a long
measurement) gives now.

How a quoted number is pinned: each is matched in the README's text by a pin below, which says where the
number comes from: a block's output, a file a command wrote, the code, or, for measurements that take
minutes to hours (the volumetric solver, the 16-test validation sweep), the page of docs/ that records
them with their commands. A quoted number agrees when it is within one unit of its last digit of the value
(``0.259`` within 0.001, ``60`` within 1). A quoted time is an upper bound on 2 cores; the test allows
twice it, as the machine may be shared, and prints the time it measured. Every number in the README's
text and code comments is either pinned or listed in ``NOT_RESULTS`` with the reason (citations, section
numbers, notation, the inputs of a command), so a new number needs a pin.
"""

from __future__ import annotations

import json
import os
import re
import resource
import shutil
import subprocess
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from conftest import ROOT

README = ROOT / "README.md"
DOCS = ROOT / "docs"
VENV_BIN = ROOT / ".venv" / "bin"
#: the user pages of docs/ (docs/configuration.md is generated from the schemas and names no command)
USER_PAGES = sorted(p for p in DOCS.glob("*.md") if p.name != "configuration.md")
#: a command or snippet that takes more than about a minute runs only with ``-m slow``
SLOW = ("my.toml", "knitframe ladder")
#: the README's design command, whose outputs the design numbers are read from
DESIGN = "design --example --out sleeve"
#: the allowance on a quoted time (an upper bound on 2 cores; the test machine may be shared)
TIME_FACTOR = 2.0
NUMBER = re.compile(r"(?<![\w.])\d+(?:\.\d+)?")


# --------------------------------------------------------------------------------------- the README
@dataclass
class Block:
    lang: str
    code: str
    start: int  # offset of the fence in README.md

    @property
    def setup(self) -> bool:
        return self.lang == "bash" and self.code.startswith("python3 -m venv")


def readme() -> str:
    return README.read_text(encoding="utf-8")


def blocks(text: str | None = None) -> list[Block]:
    """The fenced code blocks, in order; a block's language is the first word after its fence."""
    text = readme() if text is None else text
    found, opened, offset = [], None, 0
    for line in text.splitlines(keepends=True):
        if line.startswith("```"):
            if opened is None:
                info = line[3:].split()
                opened = (info[0] if info else "", offset, offset + len(line))
            else:
                found.append(Block(opened[0], text[opened[2] : offset].rstrip("\n"), opened[1]))
                opened = None
        offset += len(line)
    return found


def commands(code: str) -> list[str]:
    """The command lines of a bash block, continuation lines joined."""
    return [c.strip() for c in code.replace("\\\n", " ").splitlines() if c.strip() and not c.startswith("#")]


def steps(text: str | None = None) -> list[tuple[str, str, Block]]:
    """What a reader runs, in order: ("bash", line), ("python", snippet) and ("save", path) for a config the
    text says to save. The set-up blocks are left out (they install; the suite runs inside that install)."""
    text = readme() if text is None else text
    out = []
    for b in blocks(text):
        if b.setup:
            continue
        if b.lang == "bash":
            out += [("bash", line, b) for line in commands(b.code)]
        elif b.lang == "python":
            out.append(("python", b.code, b))
        elif b.lang == "toml":
            said = re.findall(r"[Ss]ave it as `([^`]+)`", text[: b.start])
            assert said, "the README shows a config without saying where to save it"
            out.append(("save", said[-1], b))
    return out


def is_slow(kind: str, what: str) -> bool:
    return kind != "save" and any(s in what for s in SLOW)


def prose_and_comments(text: str) -> str:
    """The README with code blanked out: commands, configs and snippets are inputs, run as they are; their
    comments, the text and the tables are kept. Inline code and link targets are blanked too."""

    def blank(s: str) -> str:
        return re.sub(r"[^\n]", " ", s)

    def comments_only(code: str) -> str:
        lines = []
        for line in code.split("\n"):
            i = line.find("#")
            lines.append(blank(line) if i < 0 else blank(line[:i]) + line[i:])
        return "\n".join(lines)

    for b in blocks(text):
        i = text.index("\n", b.start) + 1
        text = text[:i] + comments_only(text[i : i + len(b.code)]) + text[i + len(b.code) :]
    text = re.sub(r"`[^`\n]*`", lambda m: blank(m.group(0)), text)
    return re.sub(r"\]\([^)\s]*\)", lambda m: "]" + blank(m.group(0)[1:]), text)


# ----------------------------------------------------------------------------- running the README
@dataclass
class Ran:
    """A command line or snippet that ran: its time, output and (a snippet) the values it displays."""

    what: str
    seconds: float
    stdout: str
    shown: list = field(default_factory=list)
    cpu: float = 0.0  # CPU time of the processes it started, s


#: runs a snippet as the interactive interpreter would show it: each top-level expression's value is
#: recorded (numpy arrays and scalars as lists and floats) and written as JSON to argv[2]
DRIVER = r"""
import ast, json, sys
import numpy as np

def plain(v):
    if isinstance(v, dict):
        return {str(k): plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return plain(v.tolist())
    if isinstance(v, np.generic):
        return v.item()
    return v if isinstance(v, (int, float, str, bool, type(None))) else repr(v)

shown = []
tree = ast.parse(open(sys.argv[1], encoding="utf-8").read())
for i, node in enumerate(tree.body):
    if isinstance(node, ast.Expr):
        tree.body[i] = ast.fix_missing_locations(ast.copy_location(ast.Expr(ast.Call(
            ast.Name("__show__", ast.Load()), [node.value], [])), node))
space = {"__name__": "__main__", "__show__": lambda v: shown.append(plain(v))}
exec(compile(tree, "README.md", "exec"), space)
with open(sys.argv[2], "w", encoding="utf-8") as fh:
    json.dump(shown, fh)
"""


def mirror(at: Path) -> Path:
    """A folder that looks like a fresh clone's root to the README's commands: the venv, the docs, and the
    package as links to the real files, except knitframe/examples/data, a copy (the README saves a config
    there). Nothing the commands write reaches the repository."""
    at.mkdir()
    for name in (".venv", "docs", "plugins", "pyproject.toml", "README.md"):
        (at / name).symlink_to(ROOT / name)
    pkg, examples = at / "knitframe", at / "knitframe" / "examples"
    pkg.mkdir()
    for entry in (ROOT / "knitframe").iterdir():
        if entry.name != "examples":
            (pkg / entry.name).symlink_to(entry)
    examples.mkdir()
    for entry in (ROOT / "knitframe" / "examples").iterdir():
        if entry.name != "data":
            (examples / entry.name).symlink_to(entry)
    shutil.copytree(ROOT / "knitframe" / "examples" / "data", examples / "data")
    return at


def environment(tmp: Path) -> dict[str, str]:
    """The user's environment, with a cache of its own (a cached rung or point would not run), no bytecode
    written through the links, and the venv not activated: the README names its programs by path."""
    path = [
        p for p in os.environ.get("PATH", "").split(os.pathsep) if Path(p).resolve() != VENV_BIN.resolve()
    ]
    env = {k: v for k, v in os.environ.items() if k != "VIRTUAL_ENV"}
    return env | {
        "PATH": os.pathsep.join(path),
        "KNITFRAME_CACHE_DIR": str(tmp / "cache"),
        "PYTHONDONTWRITEBYTECODE": "1",
        "MPLBACKEND": "Agg",
    }


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_readme(tmp: Path, slow: bool) -> tuple[Path, dict[str, Ran]]:
    """Run the README's steps in order in a mirror of the root (the slow ones only if ``slow``); returns the
    mirror and what ran, by command line or snippet."""
    root, env, ran = mirror(tmp / "clone"), environment(tmp), {}
    for n, (kind, what, block) in enumerate(steps()):
        if is_slow(kind, what) and not slow:
            continue
        t0, cpu0 = time.perf_counter(), children_cpu()
        if kind == "save":
            (root / what).write_text(block.code + "\n", encoding="utf-8")
            continue
        if kind == "bash":
            proc = subprocess.run(["bash", "-c", what], cwd=root, env=env, capture_output=True, text=True)
            shown = []
        else:
            script, values = tmp / f"snippet-{n}.py", tmp / f"snippet-{n}.json"
            script.write_text(what, encoding="utf-8")
            proc = subprocess.run(
                [str(root / ".venv" / "bin" / "python"), "-c", DRIVER, str(script), str(values)],
                cwd=root,
                env=env,
                capture_output=True,
                text=True,
            )
        seconds, cpu = time.perf_counter() - t0, children_cpu() - cpu0
        assert proc.returncode == 0, f"README {kind} step failed:\n{what}\n{proc.stderr[-3000:]}"
        if kind == "python":
            shown = json.loads(values.read_text(encoding="utf-8"))
        ran[what] = Ran(what, seconds, proc.stdout, shown, cpu)
        print(f"{seconds:6.1f} s ({cpu:5.1f} s CPU)  {what.splitlines()[0][:100]}")
    return root, ran


# ----------------------------------------------------------------------------------------- the pins
@dataclass
class Pin:
    """Numbers of the README matched by ``pattern`` (its groups, in order; a space matches any whitespace),
    and where they come from: ``value(ctx)`` gives them in the same order. ``needs`` names the step (a
    substring of its command or snippet) whose output ``value`` reads; None: it needs nothing that runs.
    ``kind``: "equal", within one unit of the quoted number's last digit; "max", the value rounds to at most
    the quoted number; "time", seconds, at most TIME_FACTOR times the quoted number. A value None is
    printed, not checked (a time alone on an idle machine cannot be measured on a shared one)."""

    pattern: str
    value: Callable
    needs: str | None = None
    kind: str = "equal"


@dataclass
class Context:
    root: Path
    ran: dict[str, Ran]

    def step(self, needle: str) -> Ran:
        found = [r for w, r in self.ran.items() if needle in w]
        assert len(found) == 1, f"{len(found)} README steps contain {needle!r}"
        return found[0]

    def shown(self, needle: str) -> list:
        """The values a snippet displays, in order."""
        return self.step(needle).shown

    def design(self) -> dict:
        """The design.json the README's design command wrote."""
        folder = DESIGN.split("--out ")[1]
        return json.loads((self.root / folder / "design.json").read_text(encoding="utf-8"))


def spaced(pattern: str) -> str:
    return pattern.replace(" ", r"\s+")


def doc(name: str) -> str:
    return (DOCS / name).read_text(encoding="utf-8")


def docnum(name: str, pattern: str) -> list[float]:
    """The groups of ``pattern``'s one match in a page of docs/, as numbers."""
    found = re.findall(spaced(pattern), doc(name), re.S)
    assert len(found) == 1, f"docs/{name}: {len(found)} matches of {pattern!r}"
    return [float(g) for g in (found[0] if isinstance(found[0], tuple) else (found[0],))]


def span(values: list[float]) -> list[float]:
    return [min(values), max(values)]


def section1(fabric: str, column: int) -> list[float]:
    """A cell of docs/validation.md's section 1 table (rod defaults against P2 seed r), as numbers."""
    line = next(l for l in doc("validation.md").splitlines() if l.startswith(f"| {fabric} | defaults |"))
    return [float(x) for x in re.findall(r"[\d.]+", line.strip("|").split("|")[column])]


def hgo2m_on_singal() -> list[float]:
    """The hgo2m tension NRMSE (%) of the 16 Singal curves (acrylic and cotton) in the reduced models'
    note."""
    note = doc("notes/2026-11-27-validation-reference-checks.md")
    rows = [r.split("|") for r in note.split("| hgo2m NRMSE tension |")[1].split("\n\n")[0].splitlines()]
    return [float(r[9].strip(" %")) for r in rows if len(r) > 10 and r[1].strip() in ("acrylic", "cotton")]


def singal() -> dict[str, list[float]]:
    """docs/validation.md, section 3: the 16 real tests against the rod, the P1 and the P2 cell."""
    rod_median = (
        r"\*\*([\d.]+)\*\* over \d+ ratios at (\d+)/(\d+)/(\d+) % "
        r"\(pearl cotton \*\*([\d.]+)\*\*, acrylic ([\d.]+)\)"
    )
    median, *strains = docnum("validation.md", rod_median)
    return {
        "tests": docnum("validation.md", r"All (\d+) uniaxial tests of Singal"),
        "median": [median, strains[3], strains[4]],  # all, pearl cotton, acrylic
        "strains": strains[:3],
        "within": docnum(
            "validation.md",
            r"\*\*(\d+) of (\d+)\*\*; from ([\d.]+) \(pearl-cotton jersey, wale, at 10 %\) to (\d+) \(pearl",
        ),
        "pairs": docnum("validation.md", r"\| \*\*(\d+) of (\d+)\*\* pattern pairs in the measured order"),
        "lateral": docnum(
            "validation.md", r"lateral contraction within ([\d.]+) of the measured \| \*\*(\d+) of (\d+)\*\*"
        ),
        "p1_median": docnum(
            "validation.md",
            r"\| \*\*([\d.]+)\*\* over \d+ ratios \(pearl cotton ([\d.]+), acrylic ([\d.]+)\)",
        ),
        "p1_within": docnum("validation.md", r"\| \*\*(\d+) of (\d+)\*\*; from −"),
        "p2_minutes": docnum("validation.md", r"P2 takes (\d+)–(\d+) minutes per curve"),
        "p2": docnum("validation.md", r"median ratio ([\d.]+), (\d+) of (\d+) curves within (\d+)×"),
        "factor": docnum("validation.md", r"\| every curve within (\d+)× \|"),
    }


def uniaxial_ratios() -> list[float]:
    """Rod over P2 seed r at 30 % under a uniaxial pull with a free side (docs/validation.md, section 1)."""
    rows = (
        "jersey SL12 cotton, along the course",
        "jersey pearl cotton, 11.28 mm per stitch, along the course",
    )
    pairs = [docnum("validation.md", rf"\| {row} \| ([\d.]+) \| ([\d.]+) \|") for row in rows]
    return [rod / p2 for p2, rod in pairs]


def tight_cells_softer() -> list[float]:
    """P2 over the rod at 30 % on the tight cells (cotton SL10 and SL11), both directions."""
    return span(
        [
            p2 / rod
            for sl in ("SL10", "SL11")
            for p2, rod in zip(*(section1(f"jersey {sl} cotton", c) for c in (2, 3)))
        ]
    )


def resolved_rod() -> dict[str, list[float]]:
    """The resolved rod: its time over the defaults' (performance.md) and its NRMSE against theirs."""
    table = (
        doc("performance.md")
        .split('| fabric | default rod | `shear = "resolved"` | ratio |')[1]
        .split("\n\n")[0]
    )
    text = doc("validation.md").split("**A rod with its own shear")[1]
    pairs = re.findall(r"(\d+\.\d) % against (\d+\.\d) %", text)[:2]
    return {
        "time": span([float(r) for r in re.findall(r"\| ([\d.]+)× \|", table)]),
        "nrmse": [max(abs(float(a) - float(b)) for a, b in pairs)],
    }


def p2_seed_r_minutes() -> list[float]:
    line = next(l for l in doc("performance.md").splitlines() if l.startswith("| P2, seed r |"))
    return span([float(t) for t in re.findall(r"([\d.]+) min", line)])


def the_design_keeps_its_promises(c: Context) -> list[float]:
    d = c.design()
    assert d["prescription"]["falls_steadily"] and d["limits_respected"], (
        "not falling steadily, or over a limit"
    )
    pressures = [
        max(s["pressure_mmHg"]["equivalent"], s["pressure_mmHg"]["local_mean"]) for s in d["stations"]
    ]
    assert max(pressures) < d["safety"]["ceiling_mmHg"], "a station over the ceiling"
    everywhere = d["prescription"]["all"]
    assert everywhere["stations_inside"] == everywhere["stations"]
    return [everywhere["stations"], 100 * d["prescription"]["tolerance"]]


def stitch_lengths() -> list[float]:
    from knitframe.geometry.knit import STITCH_LENGTHS

    return [*STITCH_LENGTHS.values(), *map(float, STITCH_LENGTHS)]


def readme_max_strain() -> list[float]:
    config = tomllib.loads(next(b.code for b in blocks() if b.lang == "toml"))
    return [100 * config["scene"]["load"]["max_strain"]]


def snippet_strain(c: Context) -> float:
    return 100 * float(re.search(r"max_strain=([\d.]+)", c.step(SNIPPET_T).what).group(1))


def exit_code() -> list[float]:
    from knitframe.errors import ConfigError

    return [ConfigError.exit_code]


def max_processes() -> list[float]:
    return [float(re.search(r"--maxprocesses (\d+)", (ROOT / "pyproject.toml").read_text()).group(1))]


#: the README's snippets, by a line of each, whose displayed values are pinned
SNIPPET_FIT, SNIPPET_T, SNIPPET_DESIGN = (
    "fit.params, fit.nrmse",
    "curve.T1[-1], curve.T2[-1]",
    "sleeve.prescription()",
)
S, V = singal, resolved_rod

PINS: list[Pin] = [
    # ---- set-up and the examples: what the commands and snippets give now
    Pin(
        r"the rod solver \(about (\d+) s alone on 2 cores, (\d+)–(\d+) s with other jobs running\)",
        lambda c: [c.step("--example").cpu, None, c.step("--example").seconds],
        "--example",
        "time",
    ),
    Pin(r"as many processes as there are cores, at most (\d+)", lambda c: max_processes()),
    Pin(
        r"# a = ([\d.]+) N/mm, b = ([\d.]+), θ = ([\d.]+) rad; NRMSE ([\d.]+) %",
        lambda c: [*c.shown(SNIPPET_FIT)[0][0], 100 * c.shown(SNIPPET_FIT)[0][1]["overall"]],
        SNIPPET_FIT,
    ),
    Pin(r"under equibiaxial stretch to (\d+) %", lambda c: readme_max_strain()),
    Pin(
        r"machine setting \(([\d.]+)/([\d.]+)/([\d.]+) mm at (\d+)/(\d+)/(\d+)\)", lambda c: stitch_lengths()
    ),
    Pin(
        r"Then run it \(about (\d+) s alone on 2 cores, about a (minute) with other jobs running\)",
        lambda c: [c.step("--out results").cpu, c.step("--out results").seconds],
        "--out results",
        "time",
    ),
    Pin(
        r"# tension at (\d+) %, N/mm \(([\d.]+), ([\d.]+)\)",
        lambda c: [snippet_strain(c), *c.shown(SNIPPET_T)[-1]],
        SNIPPET_T,
    ),
    Pin(r"library of (eight) measured fabrics", lambda c: [len(c.design()["library"]["fabrics"])], DESIGN),
    Pin(
        r"class II, ([\d.]+) mmHg at the wrist falling to (\d+) % at the top",
        lambda c: [
            c.design()["objective"]["options"]["target_mmHg"],
            100 * c.design()["objective"]["options"]["ratios"][-1],
        ],
        DESIGN,
    ),
    Pin(
        r"within ([\d.]+) % of the prescription \(RMS; the worst station ([\d.]+) %\)",
        lambda c: [100 * c.shown(SNIPPET_DESIGN)[0][0][k] for k in ("rms_error", "worst_error")],
        SNIPPET_DESIGN,
    ),
    Pin(r"all (\d+) stations within ±(\d+) %", the_design_keeps_its_promises, DESIGN),
    Pin(r"no station over the (\d+) mmHg ceiling", lambda c: [c.design()["safety"]["ceiling_mmHg"]], DESIGN),
    Pin(r"ceiling \(under (\d+) s\)", lambda c: [c.step(DESIGN).seconds], DESIGN, "time"),
    Pin(
        r"if the limb swells by (\d+) % or the fabric's pitch is off by (\d+) %",
        lambda c: [100 * c.design()["safety"][k] for k in ("limb_tolerance", "pitch_error")],
        DESIGN,
    ),
    Pin(r"naming the key and the problem \(\s*\), exit code (\d+)", lambda c: exit_code()),
    # ---- which solver: a fit, and the 16 real tests (docs/validation.md, section 3)
    Pin(r"on the (\d+) tests of Singal et al\. 2024 such a fit", lambda c: [len(hgo2m_on_singal())]),
    Pin(r"within ([\d.]+)–([\d.]+) % of the curve it was fitted to", lambda c: span(hgo2m_on_singal())),
    Pin(r"fitted to a measured test: ([\d.]+)–([\d.]+) % NRMSE \(hgo2m\)", lambda c: span(hgo2m_on_singal())),
    Pin(r"Simulated without anything tuned to them, the same (\d+) tests", lambda c: S()["tests"]),
    Pin(r"and against the (\d+) uniaxial tests of Singal", lambda c: S()["tests"]),
    Pin(r"about (half) the measured one", lambda c: S()["median"][:1]),
    Pin(
        r"tension, at (\d+), (\d+) and (\d+) % strain, is ([\d.]+) "
        r"\(pearl cotton ([\d.]+), acrylic ([\d.]+)\)",
        lambda c: S()["strains"] + S()["median"],
    ),
    Pin(
        r"(\d+) of the (\d+) curves are within (\d+)× of their test; the worst are (\d+)× too soft "
        r"\(([\d.]+) of the measured tension\) and (\d+)× too stiff",
        lambda c: (lambda n, of, lo, hi: [n, of, *S()["factor"], 1 / lo, lo, hi])(*S()["within"]),
    ),
    Pin(r"(\d+) of (\d+) pairs of patterns come out in the measured order", lambda c: S()["pairs"]),
    Pin(r"lateral contraction is within ([\d.]+) on (\d+) of the (\d+)", lambda c: S()["lateral"]),
    Pin(
        r"\(P1\) gets a median ratio of ([\d.]+) by errors of opposite sign in the two yarns, "
        r"with (\d+) of (\d+) curves within (\d+)×",
        lambda c: S()["p1_median"][:1] + S()["p1_within"] + S()["factor"],
    ),
    Pin(
        r"\(P2, (\d+)–(\d+) minutes per curve\) a median of ([\d.]+), with (\d+) of (\d+) pearl-cotton "
        r"curves within (\d+)×",
        lambda c: S()["p2_minutes"] + S()["p2"],
    ),
    # ---- which solver: the table and the text below it (docs/validation.md, performance.md, ladder.md)
    Pin(
        r"\| < (\d+) ms \|",
        lambda c: docnum("performance.md", r"\| reduced \(hgo fitted to P1 r/3\) \| 3 \| ([\d.]+) ms"),
        kind="max",
    ),
    Pin(
        r"as good as its source: ([\d.]+) % from a smooth simulated curve it is fitted to, "
        r"(\d+) % from one with a jump",
        lambda c: docnum(
            "performance.md",
            r"as good as what it is fitted to\*\*: ([\d.]+) % along the course, (\d+) % along",
        ),
    ),
    Pin(
        r"\| ([\d.]+)–([\d.]+) s \| equibiaxial",
        lambda c: docnum(
            "performance.md",
            r"10 load steps, quiet machine \(2026-11-28, `bench_rod.py --repeats 3`\) \| ([\d.]+)–([\d.]+) s",
        ),
    ),
    Pin(
        r"NRMSE ([\d.]+) % \(nylon SL11\) and ([\d.]+) % \(cotton SL12\); "
        r"([\d.]+) % and ([\d.]+) % on the tight cotton",
        lambda c: [
            section1(f, 4)[0]
            for f in ("jersey SL11 nylon", "jersey SL12 cotton", "jersey SL11 cotton", "jersey SL10 cotton")
        ],
    ),
    Pin(r"with a free side:? (?:the rod is )?([\d.]+)–(\d+)× stiffer", lambda c: span(uniaxial_ratios())),
    Pin(
        r"\(NRMSE (\d+)–(\d+) %\)",
        lambda c: docnum(
            "validation.md",
            r"along the course \| [\d.]+ \| [\d.]+ \| (\d+) %.*?"
            r"along the course \| [\d.]+ \| [\d.]+ \| (\d+) %",
        ),
    ),
    Pin(
        r"\| median ratio ([\d.]+) \(pearl cotton ([\d.]+), acrylic ([\d.]+)\); "
        r"(\d+) of (\d+) curves within (\d+)×; "
        r"(\d+) of (\d+) pattern pairs in order",
        lambda c: S()["median"] + S()["within"][:2] + S()["factor"] + S()["pairs"],
    ),
    Pin(r"\| ([\d.]+)–(\d+)× the defaults where it finishes", lambda c: V()["time"]),
    Pin(r"within (\d+) point of NRMSE", lambda c: V()["nrmse"], kind="max"),
    Pin(r"shear by up to (\d+)°", lambda c: docnum("validation.md", r"shear by up to (\d+)°")),
    Pin(
        r"\| (\d+) s \(seed r\) \|",
        lambda c: docnum("performance.md", r"\| P1, seed r \| 2 112 \| – \| (\d+) s \(alone\)"),
    ),
    Pin(
        r"\| ([\d.]+)–([\d.]+)× too stiff: locks in bending",
        lambda c: docnum("ladder.md", r"P1 at seed r carries ([\d.]+)–([\d.]+)× the tension of P2 at seed r"),
    ),
    Pin(
        r"\| median ([\d.]+) \(pearl cotton ([\d.]+), acrylic ([\d.]+)\); (\d+) of (\d+) within (\d+)× \|",
        lambda c: S()["p1_median"] + S()["p1_within"] + S()["factor"],
    ),
    Pin(r"\| (\d+)–(\d+) min \|", lambda c: p2_seed_r_minutes()),
    Pin(
        r"the reference: ([\d.]+) % \(NRMSE\) from seed r/1\.5",
        lambda c: docnum("validation.md", r"differs from it by ([\d.]+) % NRMSE"),
    ),
    Pin(
        r"\| ([\d.]+) % from seed r \|",
        lambda c: docnum("validation.md", r"differs from it by ([\d.]+) % NRMSE"),
    ),
    Pin(
        r"about an (hour)",
        lambda c: [60 * docnum("performance.md", r"\| P2, r/1\.5 \| 36 378 \| – \| (\d+) min \|")[0]],
    ),
    Pin(
        r"\| 8 pearl-cotton curves: median ratio ([\d.]+); (\d+) of (\d+) within (\d+)×", lambda c: S()["p2"]
    ),
    Pin(r"is (\d+)–(\d+)× softer", lambda c: tight_cells_softer()),
    Pin(
        r"moves a rod curve with friction by up to (\d+) % at 30 % strain and (\d+) % at 5 %",
        lambda c: docnum(
            "validation.md", r"a difference below about (\d+) % at 5 % strain and (\d+) % at 30 %"
        )[::-1],
    ),
]

#: numbers the README gives in words: (value, tolerance)
WORDS = {"eight": (8, 0), "half": (0.5, 0.1), "minute": (60, 0), "hour": (3600, 900)}

#: numbers of the README that are not results, each with why
NOT_RESULTS: list[tuple[str, str]] = [
    (r"Extreme Mechanics Letters, 2026|Crane 2023|NOMAD 4|RAL-GZ 387", "citations and names"),
    (
        r"Singal et al\. 2024|Nature Communications 15, 2622 \(2024\)|doi:10\.1038/s41467-024-46498-z"
        r"|Copyright \(c\) 2023",
        "citations",
    ),
    (r"^\d\. \*\*", "list numbering"),
    (r"2×2 cell|2x2 periodic|1×1 tuck|ψ = a/b·\[exp\(b\(I4−1\)²\)−1\]", "the model's definitions"),
    (r"section \d", "section numbers of docs/validation.md"),
    (r"on 2 cores", "the machine the times are for"),
    (r"0 → 30 %", "the load path of the measurements"),
    (r"seed r/1\.5|r/1\.5 \|", "a mesh's name: element size r/1.5"),
    (r"at (?:10–30|1\d–3\d) % strain", "where the ratio is taken: the load path"),
    (r"stitch where the loop bends at two", "the notation of the sentence"),
]


def pin_matches(text: str, pin: Pin) -> list[re.Match]:
    found = list(re.finditer(spaced(pin.pattern), text, re.M))
    assert found, f"no README text matches the pin {pin.pattern!r}"
    return found


def quoted(token: str) -> tuple[float, float]:
    """A quoted number and the tolerance it carries (one unit of its last digit)."""
    if token in WORDS:
        return WORDS[token]
    decimals = len(token.split(".")[1]) if "." in token else 0
    return float(token), 10.0**-decimals


def agrees(kind: str, value: float, token: str) -> bool:
    q, tol = quoted(token)
    if kind == "time":
        return value <= TIME_FACTOR * q
    if kind == "max":
        return value <= q + tol / 2
    return abs(value - q) <= tol * (1 + 1e-9)


def check_pin(text: str, pin: Pin, ctx: Context | None) -> list[str]:
    """The disagreements between a pin's quoted numbers and their source (an empty list: it holds)."""
    values = [None if v is None else float(v) for v in pin.value(ctx)]
    problems = []
    for m in pin_matches(text, pin):
        assert len(m.groups()) == len(values), (
            f"{pin.pattern!r}: {len(m.groups())} numbers, {len(values)} values"
        )
        for token, value in zip(m.groups(), values):
            if value is None:
                print(f"  {token:>8} README: not checked here")
                continue
            ok = agrees(pin.kind, value, token)
            unit = " s" if pin.kind == "time" else ""
            print(f"  {token:>8} README, {value:.6g}{unit} now: {'ok' if ok else 'DIFFERS'}")
            if not ok:
                problems.append(f"README quotes {token} ({m.group(0)!r}); now {value:.6g}")
    return problems


# ------------------------------------------------------------------------------------------ the tests
def test_the_readme_has_the_two_setup_commands_and_they_are_not_run():
    """Exactly two set-up blocks, recognised by their first words and left out of the steps the tests run."""
    setup = [b for b in blocks() if b.setup]
    assert (
        len(setup) == 2 and ".venv/bin/knitframe run --example" in setup[0].code and "pytest" in setup[1].code
    )
    assert all("python3 -m venv" not in what for _, what, _ in steps())


def test_every_command_names_the_venvs_programs():
    """Every command line in the README's and the user pages' code (and the README's inline commands) starts
    with .venv/bin/, the one convention the README states."""
    bare = re.compile(r"^\s*(?:\$ )?(?:cd \S+|knitframe|python|python3|pip|pytest)\s")
    for page in [README, *USER_PAGES]:
        text = page.read_text(encoding="utf-8")
        code = [b.code for b in blocks(text) if b.lang in ("bash", "sh", "console", "")]
        code += re.findall(r"^ {4}(.*)$", text, re.M)  # indented code
        for line in "\n".join(code).splitlines():
            for part in line.split("&&"):
                if part.strip().startswith("python3 -m venv"):
                    continue
                assert not bare.match(part), f"{page.name}: a command without the venv's path: {line.strip()}"
    inline = re.findall(r"`((?:knitframe|python) [^`]*)`", readme())
    assert not inline, f"README: inline commands without .venv/bin/: {inline}"
    assert "(`.venv/bin/knitframe`, `.venv/bin/python`)" in readme(), (
        "the README no longer states its convention"
    )


def test_no_step_writes_where_an_earlier_one_did():
    """The README's commands and snippets write to distinct output folders, so none stops on a folder an
    earlier line filled."""
    outs = []
    for kind, what, _ in steps():
        outs += (
            re.findall(r"--out\s+(\S+)", what)
            if kind == "bash"
            else re.findall(r"\bout\s*=\s*[\"']([^\"']+)", what)
        )
    assert outs and len(outs) == len(set(outs)), f"an output folder is written twice: {outs}"


def test_every_number_the_readme_quotes_is_pinned():
    """Each number in the README's text, tables and code comments is matched by a pin or named in
    NOT_RESULTS."""
    text = prose_and_comments(readme())
    covered = [m.span() for pin in PINS for m in pin_matches(text, pin)]
    covered += [m.span() for pattern, _ in NOT_RESULTS for m in re.finditer(spaced(pattern), text, re.M)]
    loose = []
    for m in NUMBER.finditer(text):
        if not any(a <= m.start() and m.end() <= b for a, b in covered):
            line = text.count("\n", 0, m.start()) + 1
            loose.append(f"line {line}: {m.group(0)} in {text.splitlines()[line - 1].strip()[:90]!r}")
    assert not loose, "numbers the README quotes with no pin:\n" + "\n".join(loose)


def test_the_numbers_from_docs_and_code_are_current():
    """The README's numbers that come from the pages recording long measurements, or from the code without
    running anything, agree with them."""
    text = prose_and_comments(readme())
    problems = [p for pin in PINS if pin.needs is None for p in check_pin(text, pin, None)]
    assert not problems, "\n".join(problems)


def check_run(tmp_path: Path, slow: bool) -> None:
    root, ran = run_readme(tmp_path, slow)
    ctx, text = Context(root, ran), prose_and_comments(readme())
    problems = []
    for pin in PINS:
        if pin.needs is None or pin.needs == "--example":
            continue
        if not any(pin.needs in what for what in ran):
            assert not slow, f"the pin's step {pin.needs!r} did not run"
            continue
        problems += check_pin(text, pin, ctx)
    assert not problems, "\n".join(problems)


def test_the_readme_runs_in_order(tmp_path):
    """The README's steps that take under a minute run in order from a copy of the root, and quote the
    numbers they give."""
    check_run(tmp_path, slow=False)


@pytest.mark.slow
def test_the_readme_runs_in_order_with_the_simulations(tmp_path):
    """Every step of the README, the simulations too, runs in order from a copy of the root, and quotes the
    numbers it gives."""
    check_run(tmp_path, slow=True)


@pytest.mark.slow
def test_the_example_takes_the_time_the_readme_quotes(tmp_path):
    """The set-up line's main job (the built-in example, after the install) runs in the time the README
    gives."""
    job = blocks()[0].code.split("&&")[-1].strip()
    assert job.startswith(".venv/bin/knitframe run --example")
    root, env = mirror(tmp_path / "clone"), environment(tmp_path)
    t0, cpu0 = time.perf_counter(), children_cpu()
    proc = subprocess.run(["bash", "-c", job], cwd=root, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    seconds, cpu = time.perf_counter() - t0, children_cpu() - cpu0
    summary = json.loads((root / "example-out" / "summary.json").read_text(encoding="utf-8"))
    simulate = next(s["seconds"] for s in summary["stages"] if s["stage"] == "simulate")
    print(
        f"{job}: {seconds:.1f} s ({cpu:.1f} s CPU), of which simulate {simulate:.1f} s; "
        f"load {os.getloadavg()}"
    )
    ran = {job: Ran(job, simulate, proc.stdout, cpu=cpu)}
    ctx, text = Context(root, ran), prose_and_comments(readme())
    problems = [p for pin in PINS if pin.needs == "--example" for p in check_pin(text, pin, ctx)]
    assert not problems, "\n".join(problems)


def test_the_ladder_page_shows_the_shipped_config():
    """docs/ladder.md's config is knitframe/examples/ladder-singal.toml, whose command it gives, and it builds
    into its stages."""
    from knitframe.config import load_toml
    from knitframe.pipeline import Pipeline

    path = ROOT / "knitframe" / "examples" / "ladder-singal.toml"
    page = doc("ladder.md")
    shown = next(b.code for b in blocks(page) if b.lang == "toml")
    lines = path.read_text(encoding="utf-8").splitlines()
    header = next(i for i, line in enumerate(lines) if line and not line.startswith("#"))
    assert shown.strip() == "\n".join(lines[header:]).strip()
    assert ".venv/bin/knitframe ladder knitframe/examples/ladder-singal.toml --out ladder-out" in page
    pipeline = Pipeline(load_toml(path), base_dir=path.parent, source=str(path))
    assert pipeline.stages
