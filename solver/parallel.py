"""Sparse matrix-vector products on several cores.

SciPy's CSR products release the GIL, so splitting a matrix into row blocks
and multiplying the blocks on a thread pool uses every core without copying
the vector.  PCG on the Levenberg-Marquardt systems spends nearly all of its
time in such products (volume3d.py); on the 2-core machine of bench/ this
halves the time of one CG step at 78k tets (bench/RESULTS.md).

The number of threads is the number of usable cores; ``set_threads(1)`` (or
the environment variable SYMFRAMES_THREADS=1) turns the splitting off.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

# below this many nonzeros a product takes well under a millisecond and the
# hand-off to a thread costs more than it saves
MIN_NNZ = 100_000

_pool: ThreadPoolExecutor | None = None
_threads: int | None = None


def _usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def threads() -> int:
    """Threads used for large sparse products."""
    global _threads
    if _threads is None:
        env = os.environ.get("SYMFRAMES_THREADS", "").strip()
        try:
            _threads = max(1, int(env)) if env else min(_usable_cores(), 8)
        except ValueError as err:
            raise ValueError(f"SYMFRAMES_THREADS must be a positive integer, got {env!r}") from err
    return _threads


def set_threads(n: int) -> None:
    """Use n threads for large sparse products (1: no threads)."""
    global _threads, _pool
    if int(n) < 1:
        raise ValueError(f"the number of threads must be at least 1, got {n}")
    _threads = int(n)
    if _pool is not None:
        _pool.shutdown(wait=False)
        _pool = None


def _forget_pool_in_child() -> None:
    # a forked child (multiprocessing, the LU baseline) inherits the pool
    # object but not its threads: give it a fresh one on first use
    global _pool
    _pool = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool_in_child)


def _get_pool() -> ThreadPoolExecutor:
    global _pool
    if _pool is None:
        _pool = ThreadPoolExecutor(max_workers=max(1, threads() - 1), thread_name_prefix="symframes-spmv")
    return _pool


class RowSplitMatrix:
    """A CSR matrix whose products with vectors (or blocks of vectors) run
    by row blocks of about equal nonzero count on the thread pool."""

    def __init__(self, A: sp.spmatrix, parts: int):
        A = sp.csr_matrix(A)
        self.shape = A.shape
        self.dtype = A.dtype
        self.nnz = A.nnz
        # row boundaries that split the nonzeros evenly
        cuts = np.searchsorted(A.indptr, np.linspace(0, A.nnz, parts + 1)[1:-1])
        self.bounds = np.unique(np.r_[0, cuts, A.shape[0]])
        # the blocks are views of A's arrays (no copy of the values)
        ip = A.indptr
        self.blocks = [sp.csr_matrix((A.data[ip[a]:ip[b]], A.indices[ip[a]:ip[b]], ip[a:b + 1] - ip[a]),
                                     shape=(b - a, A.shape[1]))
                       for a, b in zip(self.bounds[:-1], self.bounds[1:])]

    def __matmul__(self, x):
        out = np.empty((self.shape[0],) + np.shape(x)[1:], dtype=np.result_type(self.dtype, x))
        b = self.bounds

        def work(i):
            out[b[i]:b[i + 1]] = self.blocks[i] @ x

        futures = [_get_pool().submit(work, i) for i in range(1, len(self.blocks))]
        work(0)
        for f in futures:
            f.result()
        return out


def parallel(A: sp.spmatrix):
    """A, or a row-split version of it when it is large enough to gain from
    the thread pool.  Either way the result supports ``A @ x``."""
    n = threads()
    if n <= 1 or not sp.issparse(A) or A.nnz < MIN_NNZ:
        return A
    return RowSplitMatrix(A, n)
