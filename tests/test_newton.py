"""Newton driver, load continuation with cut-back, and step checkpoints."""

from __future__ import annotations

import attrs
import numpy as np
import pytest
import scipy.sparse as sp
from knitframe_linsolvers.direct import direct

from knitframe.errors import NumericalError
from knitframe.numerics.continuation import StepCheckpoints, continuation
from knitframe.numerics.newton import NewtonOptions, minimise


def quartic(x, order=2):
    """E = Σ (x_i − i)⁴/4 + (x_i − i)²/2: convex, minimum at x_i = i."""
    r = x - np.arange(len(x))
    E = float(np.sum(r**4 / 4 + r**2 / 2))
    g = r**3 + r if order >= 1 else None
    H = sp.diags(3 * r**2 + 1).tocsr() if order >= 2 else None
    return E, g, H, {}


def test_minimise_converges_from_far_away():
    """Newton with line search reaches the minimum of a stiff convex energy."""
    res = minimise(
        quartic, np.full(6, 50.0), np.ones(6, bool), solve=direct(), options=NewtonOptions(rtol=0.0)
    )
    assert res.converged and np.allclose(res.x, np.arange(6), atol=1e-8)


def test_history_records_the_accepted_step_energy():
    """Each iteration records the energy of its accepted step as the line search saw it; on a plain energy
    that is the next iterate's energy (a problem that changes between evaluations shows up as a difference).
    """
    res = minimise(
        quartic, np.full(6, 50.0), np.ones(6, bool), solve=direct(), options=NewtonOptions(rtol=0.0)
    )
    steps = [h for h in res.history if "step_energy" in h]
    assert len(steps) == len(res.history) - 1
    assert all(a["step_energy"] == b["energy"] for a, b in zip(res.history[:-1], res.history[1:]))

    calls = []

    def drifting(x, order=2):  # the energy gains a constant at every Hessian evaluation: a "pairing change"
        E, g, H, info = quartic(x, order)
        if order == 2:
            calls.append(1)
        return E + 1e-3 * len(calls), g, H, info

    res = minimise(
        drifting, np.full(6, 5.0), np.ones(6, bool), solve=direct(), options=NewtonOptions(rtol=0.0)
    )
    jumps = [b["energy"] - a["step_energy"] for a, b in zip(res.history[:-1], res.history[1:])]
    assert np.allclose(jumps, 1e-3)


def test_fixed_dofs_keep_their_values():
    """DOFs outside the free mask are not moved."""
    free = np.array([True, False, True, True])
    res = minimise(quartic, np.full(4, 7.0), free, solve=direct())
    assert res.x[1] == 7.0 and np.allclose(res.x[free], np.arange(4)[free], atol=1e-8)


def test_singular_hessian_is_shifted_not_nan():
    """A flat direction (zero Hessian) is handled by the Levenberg shift and the answer is unaffected."""

    def flat(x, order=2):
        E, g, H, info = quartic(x[:2], order)
        g = None if g is None else np.append(g, 0.0)
        H = None if H is None else sp.block_diag([H, sp.csr_matrix((1, 1))]).tocsr()
        return E, g, H, {"loose": True}

    for stab in (0.0, 1e-3):
        res = minimise(
            flat,
            np.array([5.0, 5.0, 3.0]),
            np.ones(3, bool),
            solve=direct(),
            options=NewtonOptions(stabilisation=stab),
            stabilise=lambda info: info["loose"],
        )
        assert res.converged and np.allclose(res.x, [0, 1, 3], atol=1e-8)


def test_inadmissible_start_raises_numerical_error():
    """An infinite starting energy stops with a NumericalError, never NaN."""
    with pytest.raises(NumericalError, match="inadmissible"):
        minimise(
            lambda x, o=2: (np.inf, np.zeros(1), sp.eye(1).tocsr(), {}),
            np.zeros(1),
            np.ones(1, bool),
            solve=direct(),
        )


def test_unbounded_energy_fails_with_diagnostic():
    """An energy without minimum ends in a NumericalError that carries the iteration history."""

    def down(x, order=2):
        return float(-x[0]), np.array([-1.0]), sp.csr_matrix(np.array([[0.0]])), {}

    with pytest.raises(NumericalError, match="it "):
        minimise(down, np.zeros(1), np.ones(1, bool), solve=direct(), options=NewtonOptions(max_iter=5))


def kinked(x, order=2):
    """A stiff spring K(x − 1)²/2 plus a friction-like kink c|x − b|: the minimum sits at the kink b,
    where |g| ≥ c − K|b − 1| > 0 never reaches a small absolute tolerance. The spring carries the
    force flux q̃ = K|x| + c."""
    K, c, b = 1e3, 2.0, 1.001
    E = float(0.5 * K * (x[0] - 1.0) ** 2 + c * abs(x[0] - b))
    g = np.array([K * (x[0] - 1.0) + c * np.sign(x[0] - b)]) if order >= 1 else None
    H = sp.csr_matrix(np.array([[K]])) if order >= 2 else None
    return E, g, H, {"flux": K * abs(x[0]) + c}


def test_flux_test_converges_where_the_residual_has_a_floor():
    """max|g| ≤ R_n·q̃ with a small last correction is converged (ABAQUS's R_n, C_n); without it the kink
    stalls."""
    with pytest.raises(NumericalError, match="no convergence|no descent") as failed:
        minimise(kinked, np.zeros(1), np.ones(1, bool), solve=direct(), options=NewtonOptions(max_iter=30))
    history = failed.value.history  # the whole history travels with the error, for traces
    assert len(history) == 31 and history[0]["it"] == 0 and min(h["residual"] for h in history) >= 1.0 - 1e-9
    res = minimise(
        kinked,
        np.zeros(1),
        np.ones(1, bool),
        solve=direct(),
        options=NewtonOptions(max_iter=30, flux_rtol=5e-3, correction_rtol=1e-2),
    )
    assert res.converged and "flux" in res.history[-1]
    assert abs(res.x[0] - 1.001) <= 1e-2 * 1.001
    assert abs(res.gradient[0]) <= 5e-3 * kinked(res.x, 1)[3]["flux"]


def test_stalled_iteration_gives_up_early():
    """With stall_iterations = K, an iteration whose residual has not improved in K iterations stops there."""
    with pytest.raises(NumericalError, match="stalled") as failed:
        minimise(
            kinked,
            np.zeros(1),
            np.ones(1, bool),
            solve=direct(),
            options=NewtonOptions(max_iter=30, stall_iterations=5),
        )
    residuals = [h["residual"] for h in failed.value.history]
    assert len(residuals) == 9 and min(residuals[-5:]) >= min(
        residuals[:-5]
    )  # the floor 1.0 is first met at iteration 3
    # near the tolerance (the floor 1.0 is 5 × atol) it is not given up early: it runs to max_iter
    with pytest.raises(NumericalError, match="no convergence") as near:
        minimise(
            kinked,
            np.zeros(1),
            np.ones(1, bool),
            solve=direct(),
            options=NewtonOptions(max_iter=30, atol=0.2, stall_iterations=5),
        )
    assert len(near.value.history) == 31
    # a converging iteration is not stopped
    assert minimise(
        kinked,
        np.zeros(1),
        np.ones(1, bool),
        solve=direct(),
        options=NewtonOptions(max_iter=30, flux_rtol=5e-3, stall_iterations=5),
    ).converged


def test_late_flux_ratio_applies_only_after_its_iteration():
    """R_P replaces R_n from iteration I_P on: a residual floor between the two passes late, not early."""

    def floor(x, order=2):  # near the kink |g| ≥ 1: above R_n·q̃ = 0.5, below R_P·q̃ = 2
        E, g, H, info = kinked(x, order)
        return E, g, H, {"flux": 1e2}

    strict = NewtonOptions(max_iter=30, flux_rtol=5e-3, correction_rtol=1.0)
    with pytest.raises(NumericalError):
        minimise(floor, np.zeros(1), np.ones(1, bool), solve=direct(), options=strict)
    res = minimise(
        floor,
        np.zeros(1),
        np.ones(1, bool),
        solve=direct(),
        options=NewtonOptions(
            max_iter=30, flux_rtol=5e-3, correction_rtol=1.0, late_flux_rtol=2e-2, late_iteration=3
        ),
    )
    assert res.converged and res.iterations >= 3 and abs(res.gradient[0]) <= 2e-2 * 1e2


def test_flux_test_waits_for_the_correction_to_settle():
    """A residual already below R_n·q̃ is not enough while Newton still moves the solution."""

    def loud(x, order=2):
        E, g, H, _ = quartic(x, order)
        return E, g, H, {"flux": 1e9}

    res = minimise(
        loud,
        np.full(4, 50.0),
        np.ones(4, bool),
        solve=direct(),
        options=NewtonOptions(rtol=0.0, flux_rtol=5e-3, correction_rtol=1e-3),
    )
    moved = np.max(np.abs(res.x - 50.0))
    assert res.converged and res.iterations >= 2  # iteration 1 already has |g| ≤ R_n·q̃
    # accepted once a correction fell below C_n·|Δx|; Newton's next error is smaller still
    assert np.max(np.abs(res.x - np.arange(4))) <= 1e-3 * moved


def test_continuation_cuts_back_and_reaches_every_target():
    """Increments that are too large fail, are halved, and the path still reaches each target."""
    attempts = []

    def solve_at(t, x):
        attempts.append(t)
        if t - x[0] > 0.3:
            raise NumericalError("increment too large")
        return minimise(lambda y, o=2: quartic(y - t, o), x, np.ones(1, bool), solve=direct())

    reached = []
    out = continuation(solve_at, np.zeros(1), [1.0, 2.0], on_target=lambda i, t, r: reached.append(t))
    assert reached == [1.0, 2.0] and out[-1].x[0] == pytest.approx(2.0)
    assert len(attempts) > 4


def test_continuation_carries_the_increment_into_the_next_target():
    """After a target reached with small increments, the next one starts from twice that increment, not its
    span."""
    attempts = []

    def solve_at(t, x):
        attempts.append(round(t - x[0], 6))
        if t - x[0] > 0.3:
            raise NumericalError("increment too large")
        return minimise(lambda y, o=2: quartic(y - t, o), x, np.ones(1, bool), solve=direct())

    continuation(solve_at, np.zeros(1), [1.0, 2.0, 3.0])
    failed = [a for a in attempts if a > 0.3]
    assert failed[:3] == [
        1.0,
        0.5,
        0.5,
    ]  # the first target halves its way down (0.25 passes, 0.5 fails again)
    assert attempts.count(1.0) == 1  # later targets never retry the whole span


def test_continuation_gives_up_below_the_smallest_increment():
    """A step that never converges stops with a NumericalError naming the load parameter."""

    def solve_at(t, x):
        raise NumericalError("never")

    with pytest.raises(NumericalError, match="cut back"):
        continuation(solve_at, np.zeros(1), [1.0], min_fraction=1 / 8)


def test_checkpoints_round_trip_and_ignore_other_runs(tmp_path):
    """The latest step of the same key comes back; another key's files are ignored."""
    a = StepCheckpoints(tmp_path, "run-a")
    a.save(0, {"q": np.zeros(3)}, {"phase": "load"})
    a.save(1, {"q": np.ones(3)}, {"phase": "load"})
    idx, arrays, meta = a.latest()
    assert idx == 1 and np.array_equal(arrays["q"], np.ones(3)) and meta["phase"] == "load"
    assert StepCheckpoints(tmp_path, "run-b").latest() is None


def test_levenberg_shift_is_capped():
    """A kink the Hessian does not see (E = |x − 0.3| + ½(y − 1)², H = diag(1e-6, 1)) needs ever larger
    shifts as x nears the kink. The shift never exceeds 1e-8·10^(k−1), k = max_shift_increases: the
    iteration gives up there (the cut-back's turn) instead of ratcheting the shift, carried from one
    iteration to the next, up to 1e15 × the diagonal with dozens of line searches per iteration."""

    def kinked(x, order=2):
        E = float(abs(x[0] - 0.3) + 0.5 * (x[1] - 1) ** 2)
        g = np.array([np.sign(x[0] - 0.3), x[1] - 1]) if order >= 1 else None
        H = sp.diags([1e-6, 1.0]).tocsr() if order >= 2 else None
        return E, g, H, {}

    opts = NewtonOptions(max_shift_increases=14, max_backtracks=3, max_iter=60)
    with pytest.raises(NumericalError, match=r"shift up to 1e\+05") as err:
        minimise(kinked, np.array([0.0, 0.0]), np.ones(2, bool), solve=direct(), options=opts)
    assert max(h["shift"] for h in err.value.history) <= 1e5


def test_step_limit_keeps_newton_on_the_near_side_of_a_barrier():
    """A thin barrier wall at x = 1 (b = −κ(d − d̂)² ln(d/d̂) for distance d < d̂) in front of the minimum
    of ½(x − 2)²: the full Newton step from x = 0 jumps over the wall to the lower energy behind it;
    bounded by ``step_limit`` (the fraction of a step before it reaches the wall) it stops in front."""
    dhat, kappa = 0.05, 1e-2

    def fun(x, order=2):
        d = abs(x[0] - 1.0)
        if d == 0.0:
            return np.inf, None, None, {}
        s = np.sign(x[0] - 1.0)
        E, g, h = 0.5 * (x[0] - 2.0) ** 2, x[0] - 2.0, 1.0
        if d < dhat:
            E += -kappa * (d - dhat) ** 2 * np.log(d / dhat)
            g += s * -kappa * (2 * (d - dhat) * np.log(d / dhat) + (d - dhat) ** 2 / d)
            h += -kappa * (2 * np.log(d / dhat) + 4 * (d - dhat) / d - (d - dhat) ** 2 / d**2)
        return E, np.array([g]), sp.csr_matrix([[h]]), {}

    def limit(x, dx):  # the first contact with the wall along the step, 80 % of the way
        t = (1.0 - x[0]) / dx[0] if (1.0 - x[0]) * dx[0] > 0 else np.inf
        return min(1.0, 0.8 * t)

    opts = NewtonOptions(atol=1e-10, rtol=0.0, max_iter=200)
    free = np.ones(1, bool)
    jumped = minimise(fun, np.zeros(1), free, solve=direct(), options=opts)
    assert jumped.converged and jumped.x[0] == pytest.approx(2.0)
    held = minimise(fun, np.zeros(1), free, solve=direct(), options=opts, step_limit=limit)
    assert held.converged and 1.0 - dhat < held.x[0] < 1.0


def test_cap_shift_damps_a_floppy_mode_instead_of_shrinking_the_whole_step():
    """x1 is held only by a tiny spring against a force: its Newton step is far over the step cap. Without
    ``cap_shift`` the whole step is scaled down, and x0's part with it; with it the Levenberg shift rises
    (one more solve each time) until the step is within cap_shift × the cap, so x1's step is damped
    while x0 keeps most of its own."""
    eps, force = 1e-6, 1e-3
    steps = []

    def fun(x, order=2):
        E = 0.5 * (x[0] - 1.0) ** 2 + 0.5 * eps * x[1] ** 2 - force * x[1]
        return E, np.array([x[0] - 1.0, eps * x[1] - force]), sp.diags([1.0, eps]).tocsr(), {}

    def norm(dx):
        steps.append(dx.copy())
        return float(np.max(np.abs(dx)))

    def first_step(cap_shift):
        steps.clear()
        solves = []
        solve = direct()
        opts = NewtonOptions(atol=1e-9, rtol=0.0, max_iter=1, max_step=0.5, cap_shift=cap_shift)
        with pytest.raises(NumericalError):  # one iteration is not enough to converge
            minimise(
                fun,
                np.zeros(2),
                np.ones(2, bool),
                solve=lambda A, b: solves.append(1) or solve(A, b),
                options=opts,
                step_norm=norm,
            )
        return steps[0], steps[-1], len(solves)  # the raw first step, the accepted one (its correction)

    raw, scaled, n_scaled = first_step(0.0)
    _, damped, n_damped = first_step(4.0)
    assert n_scaled == 1 and raw[1] == pytest.approx(force / eps)  # the raw step: x1 ≫ the cap
    assert scaled[0] < 1e-3  # scaled whole to the cap: x0 moved 0.5 / 1000 of its Newton step 1
    assert n_damped > 1  # re-solved with larger shifts until the step was within 4 × the cap
    assert damped[0] > 0.2 and abs(damped[1]) <= 0.5 + 1e-12  # x0 keeps a quarter of its step or more


def double_well_chain(x, order=2, projected=False):
    """E = Σ a(x_i² − 1)²/4 + ½ Σ (x_{i+1} − x_i)², a = 10: each well is concave for |x_i| < 1/√3.

    ``projected`` clamps the wells' curvature a(3x² − 1) at zero (the springs are convex), the
    per-element PSD projection of projected Newton.
    """
    a = 10.0
    d = np.diff(x)
    E = float(np.sum(a * (x**2 - 1) ** 2 / 4) + 0.5 * np.sum(d**2))
    if order == 0:
        return E, None, None, {}
    g = a * x * (x**2 - 1)
    g[:-1] -= d
    g[1:] += d
    H = None
    if order == 2:
        w = a * (3 * x**2 - 1)
        if projected:
            w = np.maximum(w, 0.0)
        n = len(x)
        lap = sp.diags([np.r_[1.0, 2.0 * np.ones(n - 2), 1.0], -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1])
        H = (sp.diags(w) + lap).tocsr()
    return E, g, H, {}


def _chain(projection):
    x0 = np.r_[1.0, np.full(7, 0.05)]
    free = np.r_[False, np.ones(7, bool)]
    opts = NewtonOptions(atol=1e-12, rtol=0.0, max_iter=100, projection=projection, max_step=0.5)
    return minimise(
        double_well_chain,
        x0,
        free,
        solve=direct(),
        options=opts,
        step_norm=lambda dx: float(np.max(np.abs(dx))),
    )


@pytest.mark.parametrize("projection", ["adaptive", "always"])
def test_projected_newton_goes_downhill_to_the_minimum(projection):
    """From inside the concave band the chain (x₀ held at 1) goes down to x = 1; the adaptive mode switches
    to the projected Hessian there and back to the exact one near the minimum."""
    res = _chain(projection)
    assert res.converged and np.allclose(res.x, 1.0, atol=1e-9)
    used = [bool(h.get("projected")) for h in res.history[:-1]]
    if projection == "always":
        assert all(used)
    else:
        assert used[0] and not used[-1]  # projected where the exact step failed, exact at the end
        assert not any(used[used.index(False) :])


def test_exact_newton_stops_at_a_saddle_of_the_concave_band():
    """The same start with the exact (indefinite) Hessian: Newton's steps head for the nearest stationary
    point, and it converges to a saddle with wells at their tops (x ≈ 0) and a higher energy."""
    exact, adaptive = _chain("off"), _chain("adaptive")
    assert exact.converged and not any(h.get("projected") for h in exact.history)
    assert np.min(np.abs(exact.x)) < 0.2
    assert exact.energy > adaptive.energy + 1.0


def test_step_tolerance_stops_when_the_exact_step_is_small():
    """With ``step_tol`` an iterate whose exact Newton step moves no DOF more than step_tol is converged, even
    though its residual is above atol; the answer is then within about step_tol of the minimum."""
    opts = NewtonOptions(atol=1e-300, rtol=0.0, max_iter=100, step_tol=1e-3)
    res = minimise(
        quartic,
        np.full(6, 50.0),
        np.ones(6, bool),
        solve=direct(),
        options=opts,
        step_norm=lambda dx: float(np.max(np.abs(dx))),
    )
    assert res.converged and res.history[-1].get("step_converged")
    assert res.history[-1]["residual"] > 1e-300 and np.max(np.abs(res.x - np.arange(6))) < 1e-3
    full = minimise(
        quartic,
        np.full(6, 50.0),
        np.ones(6, bool),
        solve=direct(),
        options=attrs.evolve(opts, step_tol=0.0),
        step_norm=lambda dx: float(np.max(np.abs(dx))),
    )
    assert full.iterations > res.iterations and not full.history[-1].get("step_converged")


def test_step_tolerance_applies_to_the_projected_step():
    """Under the projection the step test is IPC's: the projected Newton step. The chain converges by it on
    projected steps alone, within about step_tol of the minimum, without the exact tangent's last iterations.
    """
    x0 = np.r_[1.0, np.full(7, 0.05)]
    free = np.r_[False, np.ones(7, bool)]
    opts = NewtonOptions(
        atol=1e-300, rtol=0.0, max_iter=100, projection="always", max_step=0.5, step_tol=1e-4
    )
    res = minimise(
        double_well_chain,
        x0,
        free,
        solve=direct(),
        options=opts,
        step_norm=lambda dx: float(np.max(np.abs(dx))),
    )
    assert res.converged and res.history[-1].get("step_converged") and res.history[-1].get("projected")
    assert np.max(np.abs(res.x - 1.0)) < 1e-3


def test_each_iteration_is_reported_as_it_completes():
    """``on_iteration`` gets every history entry (wall time included) as it is made, also when the solve
    fails."""
    seen = []
    res = minimise(
        quartic,
        np.full(6, 50.0),
        np.ones(6, bool),
        solve=direct(),
        on_iteration=seen.append,
        options=NewtonOptions(atol=1e-10, rtol=0.0, max_iter=100),
    )
    assert [h["it"] for h in seen] == [h["it"] for h in res.history]
    assert seen == list(res.history) and all(h["wall_s"] >= 0.0 for h in seen)
    seen.clear()
    with pytest.raises(NumericalError) as err:
        minimise(
            quartic,
            np.full(6, 50.0),
            np.ones(6, bool),
            solve=direct(),
            on_iteration=seen.append,
            options=NewtonOptions(atol=1e-300, rtol=0.0, max_iter=3),
        )
    assert [h["it"] for h in seen] == [0, 1, 2, 3] and len(err.value.history) == 4


def test_adaptive_newton_can_start_projected():
    """``start_projected``: the same iterates as the adaptive mode whose first exact step fails, without the
    exact Hessian (and its factorisation) of that first step."""
    calls = {False: 0, True: 0}

    def counted(x, order=2, projected=False):
        if order == 2:
            calls[projected] += 1
        return double_well_chain(x, order, projected)

    x0 = np.r_[1.0, np.full(7, 0.05)]
    free = np.r_[False, np.ones(7, bool)]
    runs = {}
    for start in (False, True):
        calls.update({False: 0, True: 0})
        opts = NewtonOptions(
            atol=1e-12, rtol=0.0, max_iter=100, projection="adaptive", max_step=0.5, start_projected=start
        )
        res = minimise(
            counted, x0, free, solve=direct(), options=opts, step_norm=lambda dx: float(np.max(np.abs(dx)))
        )
        runs[start] = (res, dict(calls))
    (plain, c_plain), (started, c_started) = runs[False], runs[True]
    assert started.converged and np.allclose(started.x, plain.x, atol=1e-12)
    assert [h["residual"] for h in started.history] == pytest.approx([h["residual"] for h in plain.history])
    assert c_started[False] == c_plain[False] - 1 and started.history[0].get("projected")


def _slow_hessian_quartic(calls):
    """``quartic`` whose Hessian costs 20 ms (as a large assembly and factorisation do), counting its
    calls."""

    def fun(x, order=2, projected=False):
        calls[order] = calls.get(order, 0) + 1
        if order == 2:
            import time

            time.sleep(0.02)
        return quartic(x, order)

    return fun


def _bounded(x, dx):
    """A CCD-like bound: no DOF moves more than 0.5 in one step."""
    return min(1.0, 0.5 / float(np.max(np.abs(dx))))


@pytest.mark.parametrize("step_tol", [0.0, 1e-6])
def test_chord_steps_reuse_the_factorisation_while_steps_are_bounded(step_tol):
    """Where a bound keeps every step short, chord steps on the kept factorisation replace most Hessians:
    the same minimum with a fraction of the Hessian evaluations, never more than max_chord chord steps in a
    row, and the step test is passed only by a Newton step."""
    n = 8
    x0 = np.full(n, 20.0)
    results, calls = {}, {}
    for chord in (False, True):
        calls[chord] = {}
        opts = NewtonOptions(atol=1e-9, rtol=0.0, max_iter=200, chord=chord, max_chord=5, step_tol=step_tol)
        results[chord] = minimise(
            _slow_hessian_quartic(calls[chord]),
            x0,
            np.ones(n, bool),
            solve=direct(),
            options=opts,
            step_limit=_bounded,
        )
    plain, chorded = results[False], results[True]
    assert plain.converged and chorded.converged
    assert np.allclose(chorded.x, np.arange(n), atol=1e-6) and np.allclose(plain.x, np.arange(n), atol=1e-6)
    assert not any(h.get("chord") for h in plain.history)
    assert (
        calls[True][2] * 3 < calls[False][2]
    )  # Hessians: each of the plain run's ~40 bounded steps needs one
    flags = [bool(h.get("chord")) for h in chorded.history]
    assert sum(flags) > len(flags) / 2
    run = longest = 0
    for f in flags:
        run = run + 1 if f else 0
        longest = max(longest, run)
    assert longest <= 5
    for h in chorded.history:
        if h.get("chord"):
            assert h["alpha0"] <= 1.0 and h["step_energy"] < h["energy"]
        if h.get("step_converged"):
            assert not h.get("chord")
    if step_tol:
        assert chorded.history[-1].get("step_converged") or chorded.history[-1]["residual"] <= 1e-9


def test_no_chord_steps_without_a_factorising_solver():
    """A linear solver without ``factorize`` (a plain function) gets Newton steps only, chord option or
    not."""
    calls = {}
    res = minimise(
        _slow_hessian_quartic(calls),
        np.full(4, 20.0),
        np.ones(4, bool),
        solve=lambda A, b: direct()(A, b),
        options=NewtonOptions(rtol=0.0, max_iter=200, chord=True),
        step_limit=_bounded,
    )
    assert res.converged and not any(h.get("chord") for h in res.history)
    assert calls[2] == len(res.history)


def test_chord_steps_stop_near_convergence_and_when_the_factor_is_stale():
    """No chord step follows a Newton step within twice step_tol (the next Newton step may pass the step
    test), and a chord step larger than twice the last Newton step is refused (the kept factorisation no
    longer models the energy): the Hessian is evaluated instead."""
    from knitframe.numerics.newton_steps import CHORD_SIZE_FACTOR, chord_step

    def size(dx):
        return float(np.max(np.abs(dx)))

    calls = {}
    opts = NewtonOptions(atol=1e-12, rtol=0.0, max_iter=200, chord=True, step_tol=1e-3)
    res = minimise(
        _slow_hessian_quartic(calls),
        np.full(5, 20.0),
        np.ones(5, bool),
        solve=direct(),
        options=opts,
        step_limit=_bounded,
        step_norm=size,
    )
    assert res.converged and any(h.get("chord") for h in res.history)
    for a, b in zip(res.history[:-1], res.history[1:]):
        if not a.get("chord") and "step" in a and a["step"] <= CHORD_SIZE_FACTOR * 1e-3:
            assert not b.get("chord")
    x = np.full(3, 5.0)
    E, g, _, _ = quartic(x, 1)
    entry = {}
    # a stale "factorisation" that sends the step 10⁴ times too far
    assert (
        chord_step(
            quartic, x, E, g, lambda b: 1e4 * b, np.ones(3, bool), opts, size, None, entry, max_size=1.0
        )
        is None
        and not entry
    )
    step = chord_step(
        quartic, x, E, g, lambda b: b / 76.0, np.ones(3, bool), opts, size, None, entry, max_size=10.0
    )
    assert step is not None and entry["chord"] and step[2] < E


def _stiff_model(calls, soft=0.05):
    """E = ½ Σ k_i x_i² + ¼ x_0⁴ with k = 1 except a soft last DOF (k = ``soft``), but a Hessian that gives
    that DOF a stiffness of 1 (as projected Newton overestimates a soft mode's curvature): full Newton steps
    then reduce the soft DOF only by the factor 1 − soft per iteration."""

    def fun(x, order=2, projected=False):
        calls.setdefault(order, []).append(x.copy())
        k = np.ones_like(x)
        k[-1] = soft
        E = 0.5 * float(k @ (x * x)) + 0.25 * x[0] ** 4
        g = k * x
        g[0] += x[0] ** 3
        d = np.ones_like(x)
        d[0] += 3.0 * x[0] ** 2
        return E, g, sp.diags(d).tocsr(), {}

    return fun


def test_extrapolation_speeds_up_full_steps_on_a_too_stiff_model():
    """Where the Hessian is 20× too stiff along a soft mode, full steps converge linearly (factor 0.95);
    extrapolating along them reaches the same minimum with half the Hessians or fewer, every extrapolated
    step within the options' limit and lowering the energy."""
    x0 = np.array([2.0, -1.0, 3.0, 10.0])
    runs = {}
    for extrapolate in (1.0, 8.0):
        calls = {}
        opts = NewtonOptions(atol=1e-8, rtol=0.0, max_iter=2000, extrapolate=extrapolate)
        res = minimise(_stiff_model(calls), x0, np.ones(4, bool), solve=direct(), options=opts)
        runs[extrapolate] = (res, len(calls[2]))
    (plain, h_plain), (fast, h_fast) = runs[1.0], runs[8.0]
    assert plain.converged and fast.converged
    assert np.allclose(fast.x, 0.0, atol=1e-6) and np.allclose(
        plain.x, 0.0, atol=1e-6
    )  # |g| ≤ 1e-8, k = 0.05
    assert not any("extrapolated" in h for h in plain.history)
    # plain full steps: 0.95 per iteration; extrapolated ones also move the stiff, converged DOFs off their
    # minimum, which the next full step restores (a zig-zag, 0.93 per iteration here); 147 against 347
    # Hessians
    assert h_fast * 2 < h_plain
    ext = [h for h in fast.history if "extrapolated" in h]
    assert ext and all(1.5 <= h["extrapolated"] <= 8.0 for h in ext)
    assert all(h["step_energy"] < h["energy"] for h in ext)
    assert all("alpha_star" in h for h in fast.history if h.get("alpha", 0.0) >= 1.0)


def test_extrapolation_keeps_to_the_step_cap_and_the_collision_bound():
    """An extrapolated step is no longer than max_step (by step_norm) and stays within the step bound."""
    calls = {}
    norm = lambda dx: float(np.max(np.abs(dx)))  # noqa: E731
    opts = NewtonOptions(atol=1e-8, rtol=0.0, max_iter=2000, extrapolate=8.0, max_step=2.0)
    res = minimise(
        _stiff_model(calls),
        np.array([0.5, 0.0, 0.0, 10.0]),
        np.ones(4, bool),
        solve=direct(),
        options=opts,
        step_norm=norm,
    )
    assert res.converged and any("extrapolated" in h for h in res.history)
    iterates = calls[2]
    assert max(norm(b - a) for a, b in zip(iterates[:-1], iterates[1:])) <= 2.0 * (1 + 1e-12)
    calls = {}
    res = minimise(
        _stiff_model(calls),
        np.array([0.5, 0.0, 0.0, 10.0]),
        np.ones(4, bool),
        solve=direct(),
        options=attrs.evolve(opts, max_step=np.inf),
        step_limit=_bounded,
    )
    assert res.converged and any("extrapolated" in h for h in res.history)
    iterates = calls[2]
    assert max(norm(b - a) for a, b in zip(iterates[:-1], iterates[1:])) <= 0.5 * (1 + 1e-12)


def test_extrapolation_backs_off_where_the_energy_rises_beyond_the_full_step():
    """Where the energy along the step grows faster than quadratically past α = 1 (a barrier), the first
    trial α* fails and a shorter α between 1.5 and α* that lowers E is taken; where every α > 1 raises E,
    the full step stands."""
    from knitframe.numerics.newton_steps import extrapolated

    opts = NewtonOptions(extrapolate=8.0)
    x, dx = np.zeros(1), np.ones(1)

    def walled(wall):
        # φ(α) = −α + 0.05 α² (α* = 10) plus a wall (α − wall)⁴·100 beyond α = wall
        def fun(y, order=0):
            a = float(y[0])
            return -a + 0.05 * a * a + 100.0 * max(a - wall, 0.0) ** 4, None, None, {}

        return fun

    fun = walled(3.0)
    E0, E1 = fun(x)[0], fun(x + dx)[0]
    entry = {}
    alpha, x_new, E_new = extrapolated(fun, x, E0, dx, -1.0, np.nan, (1.0, x + dx, E1), opts, None, entry)
    assert entry["alpha_star"] == pytest.approx(10.0)
    assert 1.5 <= alpha < 8.0 and E_new < E1 and entry["extrapolated"] == alpha
    fun = walled(1.0)
    full = (1.0, x + dx, fun(x + dx)[0])
    entry = {}
    assert extrapolated(fun, x, E0, dx, -1.0, np.nan, full, opts, None, entry) is full
    assert "extrapolated" not in entry
    # a shortened step (α < 1) is never extrapolated
    short = (0.5, x + 0.5 * dx, fun(x + 0.5 * dx)[0])
    assert extrapolated(fun, x, E0, dx, -1.0, np.nan, short, opts, None, {}) is short


class _StaleFactors:
    """A linear solver whose kept factorisations go stale: after the Newton step, their steps are 10⁴ times
    too long."""

    def __init__(self):
        self.backend = direct()

    def __call__(self, A, b):
        return self.backend(A, b)

    def factorize(self, A):
        kept = self.backend.factorize(A)
        used = []

        def apply(b):
            used.append(1)
            return kept(b) * (1.0 if len(used) == 1 else 1e4)

        apply.free = getattr(kept, "free", lambda: None)
        return apply


def test_refused_chord_steps_back_off():
    """Where every first chord step is refused (stale factors), the k-th refusal in a row skips the next 2^k −
    1 chances: of ~40 shortened Newton steps only the 1st, 3rd, 7th, 15th, ... try one (each a gradient), and
    the minimum is the same."""
    norm = lambda dx: float(np.max(np.abs(dx)))  # noqa: E731
    calls = {}
    res = minimise(
        _slow_hessian_quartic(calls),
        np.full(6, 20.0),
        np.ones(6, bool),
        solve=_StaleFactors(),
        options=NewtonOptions(atol=1e-9, rtol=0.0, max_iter=200, chord=True, max_step=1e6),
        step_limit=_bounded,
        step_norm=norm,
    )
    assert res.converged and np.allclose(res.x, np.arange(6), atol=1e-6)
    assert not any(h.get("chord") for h in res.history)
    shortened = sum(1 for h in res.history if h.get("alpha", 1.0) < 1.0)
    assert shortened > 30
    assert 1 <= calls[1] <= int(np.log2(shortened)) + 1


def _kinked_pair(x, order=2, projected=False, k=0.01, eps=1e-3):
    """E = h(x₀) + ½k·x₀² + ¼x₁⁴ with h the Huber function (|x| beyond ε, x²/2ε within: C¹ at ±ε, like
    friction's stick-slip switch). In slip the Hessian sees only k, so a full Newton step from any x₀ > ε
    lands at −1/k and the next one back at +1/k: a 2-cycle that costs no energy, which the Armijo test passes
    while x₁'s slow convergence (Newton on a quartic: ×2/3 per step) lowers E."""
    a = abs(x[0])
    h, dh, d2h = (
        (a - 0.5 * eps, np.sign(x[0]), 0.0) if a > eps else (x[0] ** 2 / (2 * eps), x[0] / eps, 1.0 / eps)
    )
    E = h + 0.5 * k * x[0] ** 2 + 0.25 * x[1] ** 4
    if order == 0:
        return E, None, None, {}
    g = np.array([dh + k * x[0], x[1] ** 3])
    H = sp.diags([d2h + k, 3.0 * x[1] ** 2 + 1e-12]).tocsr()
    return E, g, H, {}


def test_halving_breaks_a_two_cycle_across_a_kink():
    """Full Newton steps flip x₀ between ±1/k while x₁ converges (the 2-cycle of a node group across
    friction's stick-slip switch); halving a step that reverses the last move puts x₀ at the cycle's centre as
    soon as the half step's energy is lower (while x₁ is far off, its full step outweighs that: 4 iterates on
    the cycle), while without the option x₀ flips until x₁'s decrease no longer carries the Armijo test (10).
    Both reach the same minimum, and without the option no step is halved."""
    x0 = np.array([50.0, 30.0])
    runs, iterates = {}, {}
    for halve in (False, True):
        seen = iterates[halve] = []

        def fun(x, order=2, projected=False, seen=seen):
            if order == 2:
                seen.append(x.copy())
            return _kinked_pair(x, order)

        opts = NewtonOptions(atol=1e-8, rtol=0.0, max_iter=500, halve_reversals=halve)
        runs[halve] = minimise(fun, x0, np.ones(2, bool), solve=direct(), options=opts)
    plain, halved = runs[False], runs[True]
    assert plain.converged and halved.converged
    assert abs(halved.x[0]) < 1e-6 and abs(plain.x[0]) < 1e-6
    assert not any(h.get("halved") for h in plain.history)
    assert any(h.get("halved") for h in halved.history)
    cycling = {h: sum(1 for x in iterates[h] if abs(abs(x[0]) - 100.0) < 1e-6) for h in (False, True)}
    assert cycling[True] * 2 < cycling[False]


def test_chord_steps_after_full_steps_where_newton_converges_linearly():
    """On a Hessian too stiff along a soft DOF, full Newton steps converge only linearly (×0.95 per step);
    each costs a Hessian. Chord steps start only after shortened steps, so there are none; with ``chord_full``
    they follow full steps too and, at the same rate per step for a tenth of the cost, replace most Hessians.
    """
    runs = {}
    for full in (False, True):
        calls = {}
        model = _stiff_model(calls)

        def slow(x, order=2, projected=False, model=model):
            if order == 2:
                import time

                time.sleep(0.01)
            return model(x, order, projected)

        opts = NewtonOptions(atol=1e-8, rtol=0.0, max_iter=2000, chord=True, chord_full=full)
        res = minimise(slow, np.array([0.5, 0.0, 0.0, 10.0]), np.ones(4, bool), solve=direct(), options=opts)
        runs[full] = (res, len(calls[2]))
    (plain, h_plain), (chorded, h_chorded) = runs[False], runs[True]
    assert plain.converged and chorded.converged
    assert np.allclose(plain.x, 0.0, atol=1e-6) and np.allclose(chorded.x, 0.0, atol=1e-6)
    assert not any(h.get("chord") for h in plain.history)
    assert sum(1 for h in chorded.history if h.get("chord")) > len(chorded.history) / 2
    assert h_chorded * 3 < h_plain


def test_chord_full_steps_go_on_within_twice_the_step_test_under_linear_convergence():
    """Under linear convergence (×0.95 per Newton step) a full step twice the step test is ~14 steps from
    passing it: with ``chord_full`` chord steps still follow it (the observed rate predicts the next step),
    and the iteration still ends on the step test of a Newton step."""
    norm = lambda dx: float(np.max(np.abs(dx)))  # noqa: E731
    calls = {}
    opts = NewtonOptions(atol=1e-12, rtol=0.0, max_iter=2000, chord=True, chord_full=True, step_tol=1e-3)
    res = minimise(
        _stiff_model(calls),
        np.array([0.5, 0.0, 0.0, 10.0]),
        np.ones(4, bool),
        solve=direct(),
        options=opts,
        step_norm=norm,
    )
    assert res.converged and res.history[-1].get("step_converged") and not res.history[-1].get("chord")
    after_near = [
        b.get("chord", False)
        for a, b in zip(res.history[:-1], res.history[1:])
        if not a.get("chord") and a.get("alpha") == 1.0 and 1e-3 < a.get("step", 0.0) <= 2e-3
    ]
    assert any(after_near)


def test_checkpoints_after_a_step_are_discarded_for_this_run_only(tmp_path):
    """discard_after(i) removes this run's steps after i; another run's file in the folder stays."""
    mine, other = StepCheckpoints(tmp_path, "a"), StepCheckpoints(tmp_path, "b")
    for i in range(4):
        mine.save(i, {"q": np.full(2, float(i))}, {})
    other.save(5, {"q": np.zeros(2)}, {})
    mine.discard_after(1)
    assert sorted(p.name for p in tmp_path.glob("step-*.npz")) == [
        "step-0000.npz",
        "step-0001.npz",
        "step-0005.npz",
    ]
    index, arrays, _ = mine.latest()
    assert index == 1 and arrays["q"][0] == 1.0
    assert other.latest()[0] == 5
