"""Linear solver ``direct``: sparse LU/Cholesky factorisation.

Backends: SuperLU through :func:`scipy.sparse.linalg.splu` (always available), PARDISO through
``pypardiso`` and CHOLMOD through ``scikit-sparse`` when they are importable. ``backend = "auto"``
takes PARDISO for large systems when it is installed and SuperLU otherwise; CHOLMOD (symmetric
positive definite matrices only) is used when asked for.

PARDISO runs in MKL's conditional numerical reproducibility mode (:func:`_reproducible_mkl`): on two
threads, without it, eight factorisations of the same 13 824-unknown symmetric matrix gave two
different solutions, and a volumetric P2 run differed from the next in its first load step.
"""

from __future__ import annotations

import functools
import importlib.util
import os
import weakref
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from knitframe import hookimpl
from knitframe.errors import ConfigError, NumericalError

BACKENDS = ("auto", "superlu", "pardiso", "cholmod")
#: ``auto`` uses PARDISO from this many unknowns up: below (the rod cells), SuperLU is as fast and keeps
#: every digit; above, PARDISO is much faster after its one-off start-up (a P1 jersey cell, 8 091 unknowns:
#: 0.05 s against 0.45 s per new matrix; docs/performance.md, ``bench_volumetric.py iteration``)
AUTO_PARDISO_SIZE = 5_000
_MODULES = {
    "pardiso": ("pypardiso", "pip install pypardiso"),
    "cholmod": ("sksparse", "pip install scikit-sparse (needs libsuitesparse-dev)"),
}


def available(backend: str) -> bool:
    """True when the backend's library can be imported."""
    return backend == "superlu" or importlib.util.find_spec(_MODULES[backend][0]) is not None


def _superlu(A: Any, b: np.ndarray) -> np.ndarray:
    lu = spla.splu(sp.csc_matrix(A))
    x = lu.solve(np.asarray(b, dtype=np.float64))
    if not np.all(np.isfinite(x)):
        raise NumericalError("direct (SuperLU): the solution is not finite (singular matrix?)")
    return x


#: PARDISO matrix types: real symmetric indefinite (Bunch-Kaufman LDLᵀ on the upper triangle) and real
#: unsymmetric (LU)
SYMMETRIC, UNSYMMETRIC = -2, 11


def is_symmetric(A: Any, rtol: float = 1e-12) -> bool:
    """Probe of A = Aᵀ: |xᵀA y − yᵀA x| ≤ rtol·(|A y||x| + |A x||y|) for two fixed random vectors.

    Two matrix-vector products instead of forming A − Aᵀ; an unsymmetric matrix passes only if
    its skew part is below rtol (what is left is removed by the iterative refinement on A).
    """
    if A.shape[0] != A.shape[1]:
        return False
    x, y, xy = _probe_vectors(A.shape[0])
    Axy = A @ xy  # one pass over A; each column summed in the order of a matrix-vector product
    Ax, Ay = np.ascontiguousarray(Axy[:, 0]), np.ascontiguousarray(Axy[:, 1])  # strided norms are slow
    scale = float(np.linalg.norm(Ay) * np.linalg.norm(x) + np.linalg.norm(Ax) * np.linalg.norm(y))
    return abs(float(x @ Ay) - float(y @ Ax)) <= rtol * scale


@functools.lru_cache(maxsize=4)
def _probe_vectors(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two fixed random vectors x, y (n,) of :func:`is_symmetric` and the (n, 2) array of them as
    columns, all read-only."""
    rng = np.random.default_rng(12345)
    x, y = rng.standard_normal(n), rng.standard_normal(n)
    xy = np.column_stack([x, y])
    for a in (x, y, xy):
        a.flags.writeable = False
    return x, y, xy


#: above this many unknowns a failed PARDISO solve is not handed to SuperLU, whose fill-in on a 3-D
#: P2 cell runs out of memory (279 549 unknowns: over 18 GB); the caller gets a NumericalError instead
SUPERLU_FALLBACK_LIMIT = 60_000


def backward_error(A: Any, x: np.ndarray, b: np.ndarray) -> float:
    """Componentwise backward error of x (Oettli–Prager): ω = maxᵢ |b − A x|ᵢ / (|A|·|x| + |b|)ᵢ.

    The smallest ω for which x solves (A + δA) x = b + δb exactly with |δA| ≤ ω|A| and |δb| ≤ ω|b|
    entrywise; a backward-stable solve has ω of a few machine epsilons whatever the condition of A.
    """
    r = np.abs(b - A @ x)
    den = abs(A) @ np.abs(x) + np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(den > 0, r / np.where(den > 0, den, 1.0), np.where(r > 0, np.inf, 0.0))
    return float(np.max(q, initial=0.0))


#: a refined solution whose residual misses rtol is still taken when its componentwise backward error is
#: below this (≈ 45 ε): the solve is then as exact as float64 allows, and the residual floor is the
#: matrix's conditioning. Seen on the barrier Hessians of a jammed cell (gaps of 5e-8 mm, condition ~1e13):
#: every solver (PARDISO LDLᵀ or LU, SuperLU) stalls at |b − A x| ≈ 2e-10 |b|, with ω ≈ 6e-16.
BACKWARD_ERROR_TOL = 1e-14


def upper(A: Any) -> sp.csr_matrix:
    """The upper triangle (diagonal included) of a CSR matrix as a CSR matrix with sorted indices.

    A mask over the stored entries (col ≥ row) instead of scipy's triu, which goes through COO: 0.19 s
    against 0.29 s on the 2.2·10⁷ entries of a P2 r/3 Hessian (``bench_volumetric.py forms``).
    """
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:
        A = A.sorted_indices()
    n = A.shape[0]
    rows = np.repeat(np.arange(n, dtype=A.indices.dtype), np.diff(A.indptr))
    keep = A.indices >= rows
    indptr = np.zeros(n + 1, dtype=A.indptr.dtype)
    np.cumsum(np.bincount(rows[keep], minlength=n), out=indptr[1:])
    U = sp.csr_matrix((A.data[keep], A.indices[keep], indptr), shape=A.shape, copy=False)
    U.has_sorted_indices = True
    return U


def _refine(
    apply: Callable[[np.ndarray], np.ndarray], A: Any, b: np.ndarray, refine: int, rtol: float
) -> np.ndarray | None:
    """x = apply(b), then up to ``refine`` corrections x += apply(b − A x).

    Returns x once |b − A x| ≤ rtol |b|; after the last correction, the iterate of the smallest
    residual if its componentwise backward error (:func:`backward_error`) is at most
    ``BACKWARD_ERROR_TOL``; else None.
    """
    x = np.asarray(apply(b))
    b_norm = float(np.linalg.norm(b)) or 1.0
    best, best_r = None, np.inf
    for k in range(refine + 1):  # the first solve and up to ``refine`` corrections, each checked
        r = b - A @ x
        if not np.all(np.isfinite(r)):
            return None
        r_norm = float(np.linalg.norm(r))
        if r_norm <= rtol * b_norm:
            return x
        if r_norm < best_r:
            best, best_r = x, r_norm
        if k < refine:
            x = x + np.asarray(apply(r))
    if best is not None and np.all(np.isfinite(best)) and backward_error(A, best, b) <= BACKWARD_ERROR_TOL:
        return best
    return None


def _refined(solver: Any, M: Any, A: Any, b: np.ndarray, refine: int, rtol: float) -> np.ndarray | None:
    """Solve with ``solver`` (from :func:`_pardiso_solver`) on the matrix M it factorises, refine against
    A (:func:`_refine`), free the factors and make the handle idle again."""
    try:
        return _refine(lambda v: solver.solve(M, v), A, b, refine, rtol)
    finally:
        _release(solver, solver.mtype, {"released": False})


def _pardiso(A: Any, b: np.ndarray, refine: int = 4, rtol: float = 1e-10) -> np.ndarray:
    """PARDISO, then iterative refinement on the kept factors.

    A symmetric matrix (:func:`is_symmetric`; the Hessians of the energy-based solvers) is
    factorised as LDLᵀ from its upper triangle (matrix type −2, Bunch-Kaufman pivoting, which
    admits the indefinite Hessians of buckling or compressed fibres), at about half the time and
    memory of the LU (type 11) that other matrices get. PARDISO perturbs tiny pivots, which loses
    digits on badly conditioned systems (a rod's EA/EI ratio is ~1e8). Each refinement solves
    A·δ = b − A·x with the same factorisation until |b − A·x| ≤ rtol·|b|, or else takes the best iterate
    when it is backward stable (:func:`_refine`). If that fails, the LDLᵀ
    (pivots perturbed by 1e-8) is followed by the LU (1e-13, with matching and scaling), then, for
    systems up to ``SUPERLU_FALLBACK_LIMIT`` unknowns, by SuperLU; a larger system raises
    :class:`NumericalError` (Newton then shifts the matrix).
    """
    A = sp.csr_matrix(A)
    b = np.asarray(b, dtype=np.float64)
    if is_symmetric(A):
        x = _refined(_pardiso_solver(SYMMETRIC), upper(A), A, b, refine, rtol)
        if x is not None:
            return x
    x = _refined(_pardiso_solver(UNSYMMETRIC), A, A, b, refine, rtol)
    if x is not None:
        return x
    if A.shape[0] <= SUPERLU_FALLBACK_LIMIT:
        return _superlu(A, b)
    raise NumericalError(
        f"direct (PARDISO): no solution with |b − A x| ≤ {rtol:g} |b| after {refine} refinements "
        f"({A.shape[0]} unknowns, too many for the SuperLU fallback)"
    )


#: PARDISO handles whose factors were freed, by matrix type, ready for the next factorisation: building
#: a pypardiso.PyPardisoSolver searches the Python prefix for the MKL library (a recursive glob and
#: ctypes.util.find_library, which starts subprocesses), about 0.5 s each, so each is built once
_IDLE: dict[int, list[Any]] = {}


#: MKL's CNR mode "AUTO" (``mkl_cbwr_set``): the same code path on every run on this machine
MKL_CBWR_AUTO = 2


def _reproducible_mkl(solver: Any) -> None:
    """Put MKL (PARDISO's) in its conditional numerical reproducibility mode AUTO, once, unless the
    ``MKL_CBWR`` environment variable chose a mode: on a fixed number of threads its results then repeat
    bit for bit from run to run."""
    global _CBWR_SET
    if _CBWR_SET or os.environ.get("MKL_CBWR"):
        return
    _CBWR_SET = True
    lib = getattr(solver, "libmkl", None)
    if lib is not None and hasattr(lib, "MKL_CBWR_Set"):  # the C entry point (mkl_cbwr_set is Fortran's)
        lib.MKL_CBWR_Set(MKL_CBWR_AUTO)


_CBWR_SET = False


def _pardiso_solver(mtype: int = UNSYMMETRIC) -> Any:
    """An idle PARDISO handle of this matrix type, or a new one (the factors of an idle one are freed)."""
    idle = _IDLE.setdefault(mtype, [])
    if idle:
        return idle.pop()
    import pypardiso

    solver = pypardiso.PyPardisoSolver(mtype=mtype)
    _reproducible_mkl(solver)
    solver.set_iparm(8, 0)  # no internal refinement: done by _refine, where the residual is checked
    return solver


def _release(solver: Any, mtype: int, state: dict[str, bool]) -> None:
    """Free a handle's factors and make it idle again (once)."""
    if not state["released"]:
        state["released"] = True
        solver.free_memory(everything=True)
        _IDLE.setdefault(mtype, []).append(solver)


class _KeptPardiso:
    """A PARDISO factorisation kept for several right-hand sides (``x = f(b)``), refined against A."""

    def __init__(self, A: Any, refine: int, rtol: float):
        self.A = sp.csr_matrix(A)
        self.refine, self.rtol = refine, rtol
        symmetric = is_symmetric(self.A)
        self.M = upper(self.A) if symmetric else self.A.sorted_indices()
        self.mtype = SYMMETRIC if symmetric else UNSYMMETRIC
        self.solver = _pardiso_solver(self.mtype)
        self.state = {"released": False}
        try:  # analysis and factorisation (phase 12); pypardiso's factorize() would also hash the matrix
            self.solver._check_A(self.M)
            self.solver.set_phase(12)
            self.solver._call_pardiso(self.M, np.zeros((self.M.shape[0], 1)))
        except Exception as e:  # pypardiso.PyPardisoError: a zero pivot of a singular matrix
            self.free()
            raise NumericalError(f"direct (PARDISO): factorisation failed: {e}") from None

    def _apply(self, b: np.ndarray) -> np.ndarray:
        self.solver.set_phase(33)  # solve only: the factors are kept (pypardiso's solve() would hash A again)
        return np.asarray(self.solver._call_pardiso(self.M, np.ascontiguousarray(b, dtype=np.float64)))

    def __call__(self, b: np.ndarray) -> np.ndarray:
        x = _refine(self._apply, self.A, np.asarray(b, dtype=np.float64), self.refine, self.rtol)
        if x is not None:
            return x
        raise NumericalError(
            f"direct (PARDISO): no solution with |b - A x| <= {self.rtol:g} |b| from the kept "
            f"factorisation after {self.refine} refinements"
        )

    def free(self) -> None:
        _release(self.solver, self.mtype, self.state)


def _factorize_pardiso(A: Any, refine: int = 4, rtol: float = 1e-10) -> Callable[[np.ndarray], np.ndarray]:
    """PARDISO's factorisation of A kept for several right-hand sides: ``f = factorize(A); x = f(b)``.

    The same matrix types and iterative refinement as :func:`_pardiso` (its fallbacks are not
    tried: a failed kept solve raises NumericalError, and the caller factorises afresh). ``f.free()``
    releases the factors; they are also released when ``f`` is garbage-collected.
    """
    kept = _KeptPardiso(A, refine, rtol)
    weakref.finalize(kept, _release, kept.solver, kept.mtype, kept.state)
    return kept


def _factorize_superlu(A: Any) -> Callable[[np.ndarray], np.ndarray]:
    """SuperLU's LU of A kept for several right-hand sides."""
    lu = spla.splu(sp.csc_matrix(A))

    def apply(b: np.ndarray) -> np.ndarray:
        x = lu.solve(np.asarray(b, dtype=np.float64))
        if not np.all(np.isfinite(x)):
            raise NumericalError("direct (SuperLU): the solution is not finite (singular matrix?)")
        return x

    apply.free = lambda: None
    return apply


def _factorize_cholmod(A: Any) -> Callable[[np.ndarray], np.ndarray]:
    """CHOLMOD's Cholesky factor of A kept for several right-hand sides."""
    from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

    try:
        factor = cholesky(sp.csc_matrix(A))
    except CholmodNotPositiveDefiniteError as e:
        raise NumericalError(f"direct (CHOLMOD): matrix is not positive definite: {e}") from None

    def apply(b: np.ndarray) -> np.ndarray:
        return np.asarray(factor(np.asarray(b, dtype=np.float64)))

    apply.free = lambda: None
    return apply


def _cholmod(A: Any, b: np.ndarray) -> np.ndarray:
    from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

    try:
        return np.asarray(cholesky(sp.csc_matrix(A))(np.asarray(b, dtype=np.float64)))
    except CholmodNotPositiveDefiniteError as e:
        raise NumericalError(f"direct (CHOLMOD): matrix is not positive definite: {e}") from None


def direct(backend: str = "auto") -> Callable[[Any, np.ndarray], np.ndarray]:
    """Factory: ``solve(A, b)`` by sparse factorisation.

    Parameters
    ----------
    backend : {"auto", "superlu", "pardiso", "cholmod"}
        ``auto`` takes PARDISO for systems of at least ``AUTO_PARDISO_SIZE`` unknowns when
        pypardiso is installed, SuperLU otherwise. CHOLMOD is used only when asked for
        (it needs a symmetric positive definite matrix).
    """
    if backend not in BACKENDS:
        raise ConfigError("backend", f"must be one of {', '.join(map(repr, BACKENDS))}, got {backend!r}")
    if backend != "superlu" and backend != "auto" and not available(backend):
        mod, how = _MODULES[backend]
        raise ConfigError("backend", f"'{backend}' needs the {mod} package: {how}")
    if backend == "auto":
        if not available("pardiso"):
            return _with_factorize(_superlu, _factorize_superlu, "csc")

        def auto(A: Any, b: np.ndarray) -> np.ndarray:
            return (_pardiso if A.shape[0] >= AUTO_PARDISO_SIZE else _superlu)(A, b)

        def auto_factorize(A: Any) -> Callable[[np.ndarray], np.ndarray]:
            return (_factorize_pardiso if A.shape[0] >= AUTO_PARDISO_SIZE else _factorize_superlu)(A)

        return _with_factorize(auto, auto_factorize, lambda n: "csr" if n >= AUTO_PARDISO_SIZE else "csc")
    return _with_factorize(
        *{
            "superlu": (_superlu, _factorize_superlu, "csc"),
            "pardiso": (_pardiso, _factorize_pardiso, "csr"),
            "cholmod": (_cholmod, _factorize_cholmod, "csc"),
        }[backend]
    )


def _with_factorize(
    solve: Callable, factorize: Callable, fmt: str | Callable[[int], str]
) -> Callable[[Any, np.ndarray], np.ndarray]:
    """``solve(A, b)`` that also offers ``solve.factorize(A) -> f`` with ``x = f(b)`` (the factors kept) and
    ``solve.matrix_format(n)``: the sparse format ("csr" for PARDISO, "csc" for SuperLU and CHOLMOD) that an
    n × n matrix is best handed over in, with no conversion inside the solver."""

    def wrapped(A: Any, b: np.ndarray) -> np.ndarray:
        return solve(A, b)

    wrapped.factorize = factorize
    wrapped.matrix_format = fmt if callable(fmt) else (lambda n: fmt)
    return wrapped


direct.description = (
    "sparse direct factorisation: SuperLU (scipy), PARDISO (pypardiso) or CHOLMOD (scikit-sparse) "
    "when installed"
)


@hookimpl
def register_linear_solvers(register):
    register(direct, name="direct", description=direct.description)
