"""A small unit-cell solver on the run skeleton: a periodic chain of springs with closed-form tensions.

:class:`SpringCell` shows what a new unit-cell solver writes when it runs on
:class:`knitframe.numerics.cellrun.CellRun`: its model (:class:`SpringChain`, an energy
``chain(q, order) -> (E, g, H, info)`` for :func:`knitframe.numerics.newton.minimise`) and its
phase hooks (solve a pre-stress target, solve a load target, a load step's row, a state's VTU).
Pre-stress, continuation with cut-back, checkpoints and resume, VTU files and their ``.pvd``,
truncate on failure and the Response come from the skeleton. The test suite uses it to check the
skeleton against the closed form.

The cell, of size L1 × L2 (mm), holds a chain of n springs along the course direction, stiffness
k_i (N/mm) and rest length s·ℓ_i with ℓ_i = ρ L1 / n (ρ = ``rest``), closed periodically: the
last spring ends on the image of node 0 at x_0 + λ1 L1. A wale spring of stiffness k_w and rest
length s·ρ L2 spans the cell's height λ2 L2. With displacements u (n,) and macro DOFs
h = (λ1 − 1, λ2 − 1), q = [u, h] and

.. math::

    E(q) = \\sum_i \\tfrac12 k_i (d_i - s\\ell_i)^2 + \\tfrac12 k_w (\\lambda_2 L_2 - s\\rho L_2)^2,
    \\qquad d_i = x_{i+1} - x_i .

Node 0 is pinned. At equilibrium every course spring carries the same force
N = (λ1 L1 − s ρ L1) / Σ 1/k_i and the wale spring N_w = k_w (λ2 − s ρ) L2; the tensions per unit
width are the macro reactions over the cell area, T1 = ∂E/∂λ1 / (L1 L2) = N / L2 and
T2 = N_w / L1 (N/mm). A free side (uniaxial load) has λ = s ρ and T = 0. The pre-stress grows
the rest-length factor s from ``initial_size`` to 1 at λ = 1.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar, Literal

import attrs
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from knitframe.errors import NumericalError
from knitframe.numerics.cellrun import CellRun, checkpoint_key
from knitframe.numerics.continuation import StepCheckpoints
from knitframe.numerics.newton import NewtonOptions, NewtonResult, minimise
from knitframe.records import Fabric, Response, Scene

__all__ = ["SpringCell", "SpringChain"]


class SpringChain:
    """The energy of :class:`SpringCell`'s chain at rest-length factor ``s``.

    ``chain(q, order) -> (E, g, H, info)``.

    q (n + 2,) is [u_0 … u_{n−1}, λ1 − 1, λ2 − 1]; the Hessian is constant and sparse.
    """

    def __init__(self, cell: SpringCell):
        self.k = np.asarray(cell.stiffness, dtype=np.float64)
        self.n = len(self.k)
        self.k_w = float(cell.wale_stiffness)
        self.L1, self.L2 = (float(x) for x in cell.size)
        self.rest = float(cell.rest)
        self.X = np.arange(self.n) * self.L1 / self.n
        self.s = 1.0
        # d = D q + c: d_i = u_{i+1} − u_i + L1/n, the last d = u_0 − u_{n−1} + L1/n + h1·L1
        n = self.n
        rows = np.repeat(np.arange(n), 2)
        cols = np.column_stack([np.roll(np.arange(n), -1), np.arange(n)]).ravel()
        vals = np.tile([1.0, -1.0], n)
        D = sp.csr_matrix((vals, (rows, cols)), shape=(n, n + 2)).tolil()
        D[n - 1, n] = self.L1
        self.D = D.tocsr()
        K = self.D.T @ sp.diags(self.k) @ self.D
        K = K.tolil()
        K[n + 1, n + 1] = self.k_w * self.L2**2
        self.H = K.tocsr()

    @property
    def n_dof(self) -> int:
        return self.n + 2

    def lengths(self, q: np.ndarray) -> np.ndarray:
        """Spring lengths d (n,), mm."""
        return self.D @ q + self.L1 / self.n

    def __call__(self, q: np.ndarray, order: int) -> tuple[float, Any, Any, dict]:
        stretch = self.lengths(q) - self.s * self.rest * self.L1 / self.n
        wale = (1.0 + q[-1]) * self.L2 - self.s * self.rest * self.L2
        E = 0.5 * float(self.k @ stretch**2) + 0.5 * self.k_w * wale**2
        if order == 0:
            return E, None, None, {}
        g = self.D.T @ (self.k * stretch)
        g[-1] += self.k_w * wale * self.L2
        return E, g, (self.H if order == 2 else None), {}

    def write_vtu(self, path: Path, q: np.ndarray) -> Path:
        """The chain as VTU line cells (the last spring ends on node 0's image), with the displacement."""
        import meshio

        x = self.X + q[: self.n]
        image = x[0] + (1.0 + q[self.n]) * self.L1
        pts = np.zeros((self.n + 1, 3))
        pts[:, 0] = np.append(x, image)
        cells = np.column_stack([np.arange(self.n), np.arange(1, self.n + 1)])
        disp = np.zeros_like(pts)
        disp[:, 0] = pts[:, 0] - np.append(self.X, self.L1)
        meshio.write(path, meshio.Mesh(pts, [("line", cells)], point_data={"displacement": disp}))
        return Path(path)


@attrs.frozen
class SpringCell:
    """Test solver: a periodic chain of linear springs on the run skeleton (closed-form tensions)."""

    name: ClassVar[str] = "springcell"
    description: ClassVar[str] = "test solver: a periodic chain of linear springs, closed-form tensions"
    effects: ClassVar[frozenset[str]] = frozenset({"prestress"})
    loads: ClassVar[frozenset[str]] = frozenset(
        {"equibiaxial", "uniaxial-course", "uniaxial-wale", "general"}
    )

    #: stiffnesses of the course springs (their number is the chain's), N/mm
    stiffness: tuple[float, ...] = (1.0, 2.0, 4.0)
    #: stiffness of the wale spring, N/mm
    wale_stiffness: float = 3.0
    #: cell size (course, wale), mm
    size: tuple[float, float] = (2.0, 3.0)
    #: rest length of the springs / the cell's, -
    rest: float = 0.9
    #: pre-stress steps, -
    prestress_steps: int = 4
    #: rest-length factor the pre-stress starts from, -
    initial_size: float = 0.5
    #: course stretch beyond which the chain breaks (every solve there fails), -
    breaks_at: float | None = None
    #: smallest cut-back increment / step, -
    min_step_fraction: float = 1.0 / 8
    #: "truncate" returns the converged steps (converged = false)
    on_failure: Literal["raise", "truncate"] = "raise"

    def tensions(self, lam1: float, lam2: float | None = None, s: float = 1.0) -> tuple[float, float]:
        """The closed form (T1, T2), N/mm, at course stretch λ1 and wale stretch λ2 (None: free, T2 = 0)."""
        L1, L2 = self.size
        N = (lam1 - s * self.rest) * L1 / float(np.sum(1.0 / np.asarray(self.stiffness)))
        T2 = 0.0 if lam2 is None else self.wale_stiffness * (lam2 - s * self.rest) * L2 / L1
        return N / L2, T2

    def simulate(
        self,
        fabric: Fabric,
        scene: Scene,
        *,
        progress=None,
        output_dir: str | Path | None = None,
        checkpoint_dir: str | Path | None = None,
    ) -> Response:
        """Pre-stress (scene effect ``prestress``) and follow the scene's load path on the skeleton."""
        chain = SpringChain(self)
        key = checkpoint_key(fabric, scene, attrs.asdict(self))
        prestress = "prestress" in scene.effects
        run = CellRun(
            self.name,
            fabric,
            scene,
            n_prestress=self.prestress_steps if prestress else 0,
            checkpoints=None if checkpoint_dir is None else StepCheckpoints(checkpoint_dir, key),
            output_dir=output_dir,
            prefix="spring",
            write_vtu=chain.write_vtu,
            progress=progress,
            on_failure=self.on_failure,
        )
        saved = run.open()
        q = np.zeros(chain.n_dof) if saved is None else saved["q"]
        options = NewtonOptions(atol=1e-10 * float(np.max(self.stiffness)))
        n = chain.n

        def newton(q0: np.ndarray, free: np.ndarray) -> NewtonResult:
            return minimise(chain, q0, free, solve=lambda A, b: spla.spsolve(A.tocsc(), b), options=options)

        def solve_prestress(t: float, q0: np.ndarray) -> NewtonResult:
            chain.s = self.initial_size + t * (1.0 - self.initial_size)
            free = np.arange(chain.n_dof) < n
            free[0] = False  # node 0 pinned
            return newton(q0, free)

        def solve_load(tau: float, q0: np.ndarray) -> NewtonResult:
            lam = run.stretches(tau)
            if self.breaks_at is not None and lam[0] is not None and lam[0] > self.breaks_at:
                raise NumericalError(f"the chain broke at λ1 = {lam[0]:.4g}")
            qs = q0.copy()
            free = np.ones(chain.n_dof, bool)
            free[0] = False
            for d, value in enumerate(lam):
                if value is not None:
                    qs[n + d], free[n + d] = value - 1.0, False
            return newton(qs, free)

        def row(tau: float, res: NewtonResult) -> tuple[float, float, float, float]:
            T1, T2 = res.gradient[n:] / (chain.L1 * chain.L2)
            return (1.0 + res.x[n], 1.0 + res.x[n + 1], float(T1), float(T2))

        with run.truncating():
            start = int(run.state["target"])
            if run.state["phase"] == "prestress":
                if prestress:
                    q = run.prestress(
                        solve_prestress, q, first=start + 1, min_fraction=self.min_step_fraction
                    )
                start = -1
            chain.s = 1.0
            run.load(solve_load, q, float(start + 1), row=row, min_fraction=self.min_step_fraction)
        return run.response(
            source=f"springcell {fabric.pattern}",
            mesh=f"{n} springs",
            label=f"springcell {fabric.pattern} {fabric.yarn.name}",
            extra={"options": attrs.asdict(self)},
        )
