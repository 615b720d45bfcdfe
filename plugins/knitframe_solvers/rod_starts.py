"""The rod solver's pre-stress starts: the documented set, and the order a failed load path falls back in.

Stiff yarns in tight cells can be multistable: different pre-stress paths relax to different
states. The rod solver explores the starts of :data:`START_SET` (option ``starts``) and loads the
one of lowest relaxed energy; if its load path fails it falls back to the next by
:func:`fallback_order` and :func:`next_start` (see :mod:`knitframe_solvers.rod`). The run's
phases that handle several starts are :class:`MultiStart`'s.
"""

from __future__ import annotations

import time
from typing import Any, Literal, NoReturn

import attrs
import numpy as np

from knitframe import validators as v
from knitframe.errors import FieldError, NumericalError
from knitframe_solvers.rod_geometry import RodModel

__all__ = [
    "AUTO_STARTS",
    "MultiStart",
    "EXTRA_START_MIN_FRACTION",
    "SAME_ENERGY",
    "START_SET",
    "Start",
    "fallback_order",
    "first_clause",
    "loop_depth_start",
    "next_start",
    "start_count",
]


@attrs.frozen
class Start:
    """One start of the pre-stress: a rest shape, a number of pre-stress steps and a loop depth.

    ``rest``: ``"option"`` is the rest shape of the ``prestress_start`` option (for ``"auto"``: straight,
    knitted if that fails; the other way round for a shear-deformable rod); ``"other"`` is the other
    of straight and knitted. ``steps`` multiplies ``prestress_steps``. ``amplitude`` a scales the
    out-of-plane loop depth of the knitted centerlines about the cell's mid-plane: z ↦ z̄ + a (z − z̄),
    with the rest lengths unchanged.
    """

    name: str
    rest: Literal["option", "other"] = "option"
    steps: float = 1.0
    amplitude: float = 1.0


#: The documented starts, in the order they are tried; ``starts = n`` uses the first n. Each
#: reaches another relaxed state on at least one of jersey, garter, rib and seed SL11 cotton
#: (docs/notes/2026-11-26-rod-multistart.md).
START_SET: tuple[Start, ...] = (
    Start("nominal"),
    Start("other rest shape", rest="other"),
    Start("slower pre-stress", steps=1.5),
    Start("flatter loops", amplitude=0.5),
    Start("deeper loops", amplitude=1.5),
)
#: the number of starts of ``starts = "auto"``: the three that found the lowest state of jersey and rib
AUTO_STARTS = 3
#: the starts after the nominal one give up sooner: their smallest pre-stress increment, of a step
EXTRA_START_MIN_FRACTION = 1.0 / 8
#: a later start replaces the best so far only if its energy is lower by more than this, relative
SAME_ENERGY = 1e-4


def loop_depth_start(model: RodModel, amplitude: float) -> np.ndarray:
    """State q whose centerlines have the loop depth scaled by ``amplitude``.

    u_z = (a − 1)(z − z̄), no macro strain; directors (if any) along the new tangents.
    """
    q = np.zeros(model.n_dof)
    z = model.X[:, 2]
    q[2 : 3 * model.n_nodes : 3] = (amplitude - 1.0) * (z - z.mean())
    return model.aligned(q)


def start_count(instance, attribute, value) -> None:
    """``starts`` is "auto" or a whole number of starts from 1 to len(START_SET)."""
    if value == "auto":
        return
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or not 1 <= value <= len(START_SET)
    ):
        raise FieldError(
            attribute.name,
            f'must be "auto" or a whole number from 1 to {len(START_SET)}, got {v.shown(value)}',
        )


def fallback_order(starts: list[dict[str, Any]]) -> list[int]:
    """The converged starts in the order a failed load path falls back in.

    First the chosen one, then the rest by relaxed energy. The chosen start is the one
    :meth:`knitframe_solvers.rod.RodSolver.simulate` loads first: a start replaces the best so far
    only if its energy E is lower by more than :data:`SAME_ENERGY` relative. The others follow by
    E (the earlier start of a tie).
    """
    ok = [k for k, s in enumerate(starts) if s.get("converged") and s.get("energy_Nmm") is not None]
    if not ok:
        return []
    first = ok[0]
    for k in ok[1:]:
        if starts[k]["energy_Nmm"] < starts[first]["energy_Nmm"] - SAME_ENERGY * abs(
            starts[first]["energy_Nmm"]
        ):
            first = k
    return [first] + sorted((k for k in ok if k != first), key=lambda k: (starts[k]["energy_Nmm"], k))


def next_start(starts: list[dict[str, Any]], order: list[int]) -> int | None:
    """The next start to follow the load path from after a failure, or None when none is left.

    Starts whose path failed carry ``load_error``. A start whose relaxed energy is within
    :data:`SAME_ENERGY` (relative) of a failed one is the same state and would fail the same
    way: it is marked as not tried, with the failed start's name, and passed over.
    """
    failed = [k for k in order if "load_error" in starts[k]]
    for k in order:
        if "load_error" in starts[k]:
            continue
        E = starts[k]["energy_Nmm"]
        same = [
            j
            for j in failed
            if abs(E - starts[j]["energy_Nmm"]) <= SAME_ENERGY * abs(starts[j]["energy_Nmm"])
        ]
        if same:
            starts[k]["load_error"] = f"not tried: the same relaxed state as '{starts[same[0]]['name']}'"
            continue
        return k
    return None


def first_clause(message: str) -> str:
    """A NumericalError's message up to its first "; " (the Newton trace after it is left out).

    A message of several attempts joined by "; after that " (the rest shapes of one start) keeps
    the first clause of each, joined by ", then ".
    """
    return ", then ".join(part.split("; ", 1)[0] for part in message.split("; after that "))


class MultiStart:
    """The phases of a rod run with more than one start: exploring them, and falling back between them.

    A base of :class:`knitframe_solvers.rod_run.RodRun`, whose state and phases these methods use
    (``state``, ``run``, ``energy``, ``run_prestress``, ``relaxed``, ``follow_load``, …).
    """

    def start_total(self) -> int:
        """The number of starts this run explores (option ``starts``)."""
        return AUTO_STARTS if self.solver.starts == "auto" else int(self.solver.starts)

    def explore_starts(self, q_nominal: np.ndarray | None) -> np.ndarray:
        """Pre-stress and relax the other starts of :data:`START_SET`; the state of lowest energy E.

        Records every start (rest shape, pre-stress steps, loop depth, converged, E, relaxed
        stretches) in ``state["starts"]`` and the chosen one in ``state["start_chosen"]``. A
        start replaces the best so far only if its energy is lower by more than
        :data:`SAME_ENERGY` relative, so one state reached twice keeps the earlier start. The
        relaxed states go to ``start_states`` (checkpointed with every later step), from which
        a failed load path falls back to the next start (:func:`fallback_order`).

        ``q_nominal`` None: the nominal start failed (``state["nominal_error"]``, from every rest
        shape in ``state["nominal_rests"]``, or while relaxing its lattice). The other starts are
        tried all the same (with ``starts = "auto"``, all of :data:`START_SET`), the run continues
        from the lowest of those that converge with a warning saying so, and only when none
        converges does it fail, naming every start's reason.
        """
        state, energy, model = self.state, self.energy, self.model
        count = self.start_total()
        if q_nominal is None and self.solver.starts == "auto":
            count = len(START_SET)  # the nominal start failed: "auto" tries the whole set
        failed_rests = state["nominal_rests"] if q_nominal is None else []
        chosen, q_best, best = None, None, np.inf
        self.start_states = np.full((count, model.n_dof), np.nan)
        entry0 = {
            "name": START_SET[0].name,
            "rest": state["start"],
            "prestress_steps": self.solver.prestress_steps,
            "amplitude": 1.0,
        }
        if q_nominal is None:
            entry0.update(
                converged=False, energy_Nmm=None, relaxed_stretch=None, error=state["nominal_error"]
            )
        else:
            chosen, q_best, best = 0, q_nominal, float(energy(q_nominal, 0)[0])
            self.start_states[0] = q_nominal
            entry0.update(converged=True, energy_Nmm=best, relaxed_stretch=self.stretch_of(q_nominal))
        entries = [entry0]
        for k, st in enumerate(START_SET[1:count], start=1):
            rest = (
                state["start"]
                if st.rest == "option"
                else ("knitted" if state["start"] == "straight" else "straight")
            )
            steps = max(1, int(round(st.steps * self.solver.prestress_steps)))
            entry = {"name": st.name, "rest": rest, "prestress_steps": steps, "amplitude": st.amplitude}
            t0 = time.perf_counter()
            if st.steps == 1.0 and st.amplitude == 1.0 and rest in failed_rests:
                # the nominal path from this rest shape, which has already failed
                entry.update(
                    converged=False,
                    energy_Nmm=None,
                    relaxed_stretch=None,
                    error=f"not tried: the nominal start failed from the {rest} shape",
                )
                entries.append({**entry, "wall_time_s": 0.0})
                continue
            try:
                q0 = loop_depth_start(model, st.amplitude)
                qk = self.relaxed(
                    self.run_prestress(
                        rest,
                        q0,
                        0,
                        self.initial_distance(q0),
                        steps,
                        label=f" start {k + 1}/{count} ({st.name})",
                        min_fraction=max(self.solver.newton.min_step_fraction, EXTRA_START_MIN_FRACTION),
                    )
                )
                E = float(energy(qk, 0)[0])
                if not np.isfinite(E):
                    raise NumericalError(f"non-finite energy {E} at the relaxed state")
            except NumericalError as e:
                entry.update(converged=False, energy_Nmm=None, relaxed_stretch=None, error=str(e))
            else:
                entry.update(converged=True, energy_Nmm=E, relaxed_stretch=self.stretch_of(qk))
                self.start_states[k] = qk
                if chosen is None or E < best - SAME_ENERGY * abs(best):
                    chosen, q_best, best = k, qk, E
            finally:
                energy.dk = self.dk_full
            entries.append({**entry, "wall_time_s": time.perf_counter() - t0})
        state.update(starts=entries)
        if chosen is None:
            raise NumericalError(
                "no start could be pre-stressed: "
                + "; ".join(f"'{e['name']}' {first_clause(e['error'])}" for e in entries)
            )
        state["start_chosen"] = entries[chosen]["name"]
        return q_best

    def warn_nominal_failed(self) -> None:
        """If the nominal start failed, say so and which start the run continued from (also on resume)."""
        state = self.state
        if not state["nominal_error"]:
            return
        entries = state["starts"]
        self.run.warn(
            f"{self.run.where}: the nominal start failed ({first_clause(state['nominal_error'])}); "
            f"continued from the start '{state['start_chosen']}', the lowest of the "
            f"{sum(bool(e['converged']) for e in entries)} of {len(entries)} starts that converged",
            stacklevel=5,
        )

    def switch_to(self, k: int) -> np.ndarray:
        """Start k's relaxed state begins the load path: the steps from the relaxed lattice are rewritten."""
        state = self.state
        entry = state["starts"][k]
        qk = self.start_states[k].copy()
        self.run.rewind(state["relaxed_step"])
        self.run.rows.clear()
        self.snaps.clear()
        self.path_states.clear()
        self.follow.update(cut=False, last=None, lenient=-1.0)
        state.update(
            lam_ref=self.stretch_of(qk),
            relaxed_energy=float(entry["energy_Nmm"]),
            start_chosen=entry["name"],
        )
        self.lam_ref = state["lam_ref"]
        self.accept("load", -1, qk, f"relaxed lattice (start '{entry['name']}')", self.run.offset)
        return qk

    def load_phase(self, q: np.ndarray, start_index: int) -> None:
        """The load path; a start whose load path fails gives way to the next in order of relaxed energy."""
        state, rows = self.state, self.run.rows
        entries = state["starts"]
        names = [e["name"] for e in entries]
        order = fallback_order(entries)
        self.warn_nominal_failed()
        # a fallback needs the starts' relaxed states (a checkpoint of an older version has none)
        can_fall_back = (
            len(order) > 1
            and state["relaxed_step"] is not None
            and len(self.start_states) == len(entries)
            and state["start_chosen"] in names
        )
        self.path_states = []  # q of each converged load step of this path since this run began
        tried: dict[int, tuple[list, list, list]] = {}  # start -> its failed path (rows, states, snaps)
        t_at = float(start_index + 1)
        while True:
            try:
                self.follow_load(t_at, q)
                break
            except NumericalError as e:
                if not can_fall_back:
                    raise
                error = e
            current = names.index(state["start_chosen"])
            entries[current].update(
                load_error=f"after {len(rows)} of {self.run.n_load} load steps: {first_clause(str(error))}",
                load_steps=len(rows),
            )
            if len(self.path_states) == len(rows):  # the whole path is in memory (not resumed midway)
                tried[current] = (list(rows), list(self.path_states), [dict(sn) for sn in self.snaps])
            nxt = next_start(entries, order)
            if nxt is None:
                self.all_starts_failed(order, tried)
            q, t_at = self.switch_to(nxt), 0.0
        if can_fall_back and state["start_chosen"] != names[order[0]]:  # fell back
            first, used = entries[order[0]], entries[names.index(state["start_chosen"])]
            others = "".join(
                f"; nor could '{entries[k]['name']}' ({entries[k]['load_error']})"
                for k in order[1:]
                if "load_steps" in entries[k]
            )
            self.run.warn(
                f"{self.run.where}: the lowest-energy start '{first['name']}' could not follow the load "
                f"path ({first['load_error']}){others}; continued from '{used['name']}' (energy "
                f"{used['energy_Nmm'] - first['energy_Nmm']:.4g} N·mm higher)",
                stacklevel=4,
            )

    def all_starts_failed(self, order: list[int], tried: dict[int, tuple[list, list, list]]) -> NoReturn:
        """No start could follow the load path: NumericalError (truncate: the furthest rows kept first)."""
        entries = self.state["starts"]
        names = [e["name"] for e in entries]
        summary = "; ".join(f"'{entries[k]['name']}' {entries[k]['load_error']}" for k in order)
        furthest = max(order, key=lambda k: (entries[k].get("load_steps", 0), -order.index(k)))
        if self.solver.on_failure == "truncate" and entries[furthest].get("load_steps", 0) > 0:
            # keep the rows of the start that got furthest (the lower energy of a tie)
            if names[furthest] != self.state["start_chosen"]:
                q = self.switch_to(furthest)
                if furthest in tried:  # replayed from memory: no solve
                    kept_rows, kept_states, kept_snaps = tried[furthest]
                    self.snaps.extend(kept_snaps)
                    n_load, offset = self.run.n_load, self.run.offset
                    for k, (row, qv) in enumerate(zip(kept_rows, kept_states, strict=True), start=1):
                        self.run.rows.append(row)
                        self.accept("load", k - 1, qv, f"load step {k}/{n_load}", offset + k)
                else:  # tried before a resume: its path is followed again to where it fails
                    try:
                        self.follow_load(0.0, q)
                    except NumericalError:
                        pass
            summary += f"; kept the rows of '{names[furthest]}', which got furthest"
        raise NumericalError(f"no start could follow the load path: {summary}")
