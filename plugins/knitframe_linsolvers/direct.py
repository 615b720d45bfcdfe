"""Linear solver ``direct``: sparse LU/Cholesky factorisation.

Backends: SuperLU through :func:`scipy.sparse.linalg.splu` (always available), PARDISO through
``pypardiso`` and CHOLMOD through ``scikit-sparse`` when they are importable. ``backend = "auto"``
takes PARDISO, then CHOLMOD (symmetric positive definite matrices only), then SuperLU.
"""

from __future__ import annotations

import importlib.util
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from knitframe import hookimpl
from knitframe.errors import ConfigError, NumericalError

BACKENDS = ("auto", "superlu", "pardiso", "cholmod")
_MODULES = {"pardiso": ("pypardiso", "pip install pypardiso"),
            "cholmod": ("sksparse", "pip install scikit-sparse (needs libsuitesparse-dev)")}


def available(backend: str) -> bool:
    """True when the backend's library can be imported."""
    return backend == "superlu" or importlib.util.find_spec(_MODULES[backend][0]) is not None


def _superlu(A: Any, b: np.ndarray) -> np.ndarray:
    lu = spla.splu(sp.csc_matrix(A))
    x = lu.solve(np.asarray(b, dtype=np.float64))
    if not np.all(np.isfinite(x)):
        raise NumericalError("direct (SuperLU): the solution is not finite (singular matrix?)")
    return x


def _pardiso(A: Any, b: np.ndarray) -> np.ndarray:
    import pypardiso

    return np.asarray(pypardiso.spsolve(sp.csr_matrix(A), np.asarray(b, dtype=np.float64)))


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
        ``auto`` prefers PARDISO, falls back to SuperLU. CHOLMOD is used only when asked for
        (it needs a symmetric positive definite matrix).
    """
    if backend not in BACKENDS:
        raise ConfigError("backend", f"must be one of {', '.join(map(repr, BACKENDS))}, got {backend!r}")
    if backend != "superlu" and backend != "auto" and not available(backend):
        mod, how = _MODULES[backend]
        raise ConfigError("backend", f"'{backend}' needs the {mod} package: {how}")
    if backend == "auto":
        backend = "pardiso" if available("pardiso") else "superlu"
    return {"superlu": _superlu, "pardiso": _pardiso, "cholmod": _cholmod}[backend]


direct.description = "sparse direct factorisation: SuperLU (scipy), PARDISO (pypardiso) or CHOLMOD (scikit-sparse) when installed"


@hookimpl
def register_linear_solvers(register):
    register(direct, name="direct", description=direct.description)
