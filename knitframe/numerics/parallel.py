"""Thread control shared by the numerics."""

from __future__ import annotations

from threadpoolctl import threadpool_limits

__all__ = ["one_blas_thread"]


def one_blas_thread():
    """Context holding BLAS to one thread (threadpoolctl, a dependency).

    For code that runs its own threads over BLAS calls (the solid's element chunks), and for code
    that calls BLAS on tiny matrices thousands of times (L-BFGS-B on 7 × 10 matrices: on a busy
    machine OpenBLAS's worker threads cost more than the work; a 770-evaluation hgo2m fit took 9.2 s
    with 2 BLAS threads and 2.5 s with one, on 2 loaded cores).
    """
    return threadpool_limits(limits=1, user_api="blas")
