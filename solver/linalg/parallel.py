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

import itertools
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

# below this many nonzeros a product takes well under a millisecond and the
# hand-off to a thread costs more than it saves
MIN_NNZ = 100_000

_pool: ThreadPoolExecutor | None = None
_threads: int | None = None
_asked = False  # set_threads was called


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


def threads_set() -> bool:
    """Whether a thread count was asked for (SYMFRAMES_THREADS or
    set_threads), rather than taken from the cores."""
    return _asked or bool(os.environ.get("SYMFRAMES_THREADS", "").strip())


def set_threads(n: int) -> None:
    """Use n threads for large sparse products (1: no threads)."""
    global _threads, _pool, _asked
    if int(n) < 1:
        raise ValueError(f"the number of threads must be at least 1, got {n}")
    _threads, _asked = int(n), True
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


# the rows of one block give a result of at most this many bytes per
# column: SciPy allocates each block's result anew, and results beyond
# glibc's mmap threshold are fresh pages every time.  The assembly's
# scatter product (hessian.py; 10 M rows at 98k tets) took 0.28 s in two
# blocks and 0.025 s in 40.
BLOCK_BYTES = 2 << 20


class RowSplitMatrix:
    """A CSR matrix whose products with vectors (or blocks of vectors) run
    by row blocks of about equal nonzero count on the thread pool (at
    least ``parts`` blocks, more for tall matrices; the threads take the
    next block as they finish one)."""

    def __init__(self, A: sp.spmatrix, parts: int):
        A = sp.csr_matrix(A)
        self.shape = A.shape
        self.dtype = A.dtype
        self.nnz = A.nnz
        parts = max(parts, -(-A.shape[0] * 8 // BLOCK_BYTES))
        # row boundaries that split the nonzeros evenly
        cuts = np.searchsorted(A.indptr, np.linspace(0, A.nnz, parts + 1)[1:-1])
        self.bounds = np.unique(np.r_[0, cuts, A.shape[0]])
        # the blocks are views of A's arrays (no copy of the values)
        ip = A.indptr
        self.blocks = [sp.csr_matrix((A.data[ip[a]:ip[b]], A.indices[ip[a]:ip[b]], ip[a:b + 1] - ip[a]),
                                     shape=(b - a, A.shape[1]))
                       for a, b in zip(self.bounds[:-1], self.bounds[1:])]

    def __matmul__(self, x):
        return self.matvec(x)

    def matvec(self, x, out=None):
        """A @ x, written into ``out`` if given (of the result's shape and
        dtype): a kept array, unlike a fresh one, is not faulted in again."""
        shape, dtype = (self.shape[0],) + np.shape(x)[1:], np.result_type(self.dtype, x)
        if out is None:
            out = np.empty(shape, dtype=dtype)
        elif out.shape != shape or out.dtype != dtype:
            raise ValueError(f"out must have shape {shape} and dtype {dtype}, got {out.shape} {out.dtype}")
        b = self.bounds
        n = len(self.blocks)
        claim = itertools.count()  # next() on it is atomic under the GIL

        def work():
            i = next(claim)
            while i < n:
                out[b[i]:b[i + 1]] = self.blocks[i] @ x
                i = next(claim)

        futures = [_get_pool().submit(work) for _ in range(min(threads(), n) - 1)]
        work()
        for f in futures:
            f.result()
        return out


# below this length a vector operation takes well under 0.1 ms: run it whole
MIN_LEN = 100_000


def ranges(n: int) -> list:
    """Index ranges [a, b) splitting 0..n for vector work on the thread
    pool: one per thread, or a single range for short vectors."""
    k = threads() if n >= MIN_LEN else 1
    cuts = np.linspace(0, n, k + 1).astype(np.int64)
    return list(zip(cuts[:-1], cuts[1:]))


def run(work, parts: list) -> list:
    """[work(a, b) for (a, b) in parts], the parts after the first on the
    thread pool.  numpy releases the GIL in its element-wise loops and
    reductions, so memory-bound vector work on separate ranges runs on
    several cores at once."""
    if len(parts) == 1:
        return [work(*parts[0])]
    futures = [_get_pool().submit(work, a, b) for a, b in parts[1:]]
    out = [work(*parts[0])]
    out.extend(f.result() for f in futures)
    return out


def parallel(A: sp.spmatrix):
    """A, or a row-split version of it when it is large enough to gain from
    the thread pool.  Either way the result supports ``A @ x``."""
    n = threads()
    if n <= 1 or not sp.issparse(A) or A.nnz < MIN_NNZ:
        return A
    return RowSplitMatrix(A, n)
