"""The dual mesh fit's linear algebra (``swe_sphere.io.dual``): the V-cycle of smoothed
aggregation that preconditions its systems (JJᵀ + μI)y = ρ from ``dual.AMG_CELLS`` cells on."""

from __future__ import annotations

import contextlib
import ctypes
import functools
import sys

import numpy as np

PR_SET_THP_DISABLE, PR_GET_THP_DISABLE = 41, 42  # prctl(2)'s options (linux/prctl.h)
MAX_COARSE = 10  # pyamg's default: the hierarchy ends at a level of at most so many aggregates


def amg_preconditioner(A, colour):
    """One V-cycle of pyamg's smoothed aggregation for the SPD (JJᵀ + μI) ``A`` (n, n), as a
    ``LinearOperator``, from the two modes it nearly annihilates: the constant (JJᵀ·target =
    0, ``dual.dual_mesh``) and the checkerboard ``colour`` (n,) of ±1 (Jᵀ of it vanishes on a
    uniform lattice); given only the constant, aggregation misses the checkerboard (ne60: 40
    and 91 iterations where 10 and 13 with both). One Gauss–Seidel sweep before (forward)
    and after (backward) each coarse correction, a symmetric cycle, as CG needs (ne120: 12
    and 17 iterations where pyamg's default of two sweeps took 10 and 14, dearer in all). The
    prolongation's Jacobi smoothing weighted by row sums ("local"): pyamg's default weight
    needs a spectral radius estimated from a random start, which would change the cells' bits
    from run to run (and took half the set-up: ne120, 16 and 24 iterations for 1 s less).

    The hierarchy is pyamg's, built one level a call, each coarse matrix's block columns sorted
    before the next call: its "local" weighting takes |A|, which sorts an unsorted BSR matrix
    (every Galerkin product's) in a loop of Python over the block rows, 0.8 s of the 1.6 s
    set-up at ne120, where scipy's ``sort_indices`` takes 0.01 s. The cycle runs on CSR copies
    of the levels (``v_cycle``)."""
    import pyamg  # here, not at the top: a cached run never builds cells (0.15 s of imports)
    import scipy.sparse.linalg as spla

    shape = A.shape
    A.sum_duplicates()  # CSR: sorted in C (the first |A| would, in place)
    B, levels, improve = np.stack([np.ones_like(colour), colour], axis=1), [], {}
    while True:
        ml = pyamg.smoothed_aggregation_solver(
            A,
            B=B,
            symmetry="symmetric",
            smooth=("jacobi", {"weighting": "local"}),
            presmoother=("gauss_seidel", {"sweep": "forward"}),
            postsmoother=("gauss_seidel", {"sweep": "backward"}),
            max_levels=2,
            max_coarse=MAX_COARSE,
            **improve,  # pyamg's default improves the candidates on the finest level only
        )
        if len(ml.levels) == 1:  # the coarsest: its solve
            solve = functools.partial(ml.coarse_solver, A)
            cycle = functools.partial(v_cycle, levels, solve) if levels else solve
            return spla.LinearOperator(shape, cycle, dtype=A.dtype)
        fine, coarse = ml.levels
        levels.append((fine.A.tocsr(), fine.R.tocsr(), fine.P.tocsr()))
        A, B, improve = coarse.A, coarse.B, {"improve_candidates": None}
        A.sort_indices()  # BSR: sorted in C, as the next |A| would in Python


def v_cycle(levels, coarse_solver, b, lvl=0):
    """One V-cycle from zero for ``levels[lvl]``'s A x = ``b``, ``levels`` the (A, R, P) of
    pyamg's levels but the last, as CSR, and ``coarse_solver(b)`` the last's solve: pyamg's own
    cycle without the residual norms its ``solve`` takes before and after (two fine-level
    products a cycle, a sixth of its time at ne120), and with point Gauss–Seidel where pyamg's
    coarse levels (BSR, 2×2 blocks: one a candidate) take block Gauss–Seidel, twice as dear for
    the same iterations (ne120: 16 and 24 either way; 3.1 s of V-cycles where 4.3 s)."""
    from pyamg.relaxation.relaxation import gauss_seidel

    A, R, P = levels[lvl]
    x = np.zeros_like(b)
    gauss_seidel(A, x, b, sweep="forward")
    coarse_b = R @ (b - A @ x)
    coarse_x = coarse_solver(coarse_b) if lvl == len(levels) - 1 else v_cycle(levels, coarse_solver, coarse_b, lvl + 1)
    x += P @ coarse_x
    gauss_seidel(A, x, b, sweep="backward")
    return x


@contextlib.contextmanager
def small_pages():
    """This process's memory faulted in 4 kB pages inside, not transparent huge pages (Linux's
    documented ``prctl(PR_SET_THP_DISABLE)``, restored after; elsewhere, or where the call
    fails, no change). numpy asks huge pages (madvise) for its arrays of 4 MB and more, and the
    fit's temporaries of tens to hundreds of MB are mapped afresh each step: where the kernel
    compacts memory to fault them in as 2 MB pages (transparent_hugepage/defrag = madvise, the
    default) that cost 1.4–2.5 s of system CPU at ne120 where 4 kB pages cost 1.1 s, for the
    same user time and the same bits."""
    prctl = None
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            prctl = ctypes.CDLL(None, use_errno=True).prctl
    was = prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0) if prctl is not None else -1
    if was == 0 and prctl(PR_SET_THP_DISABLE, 1, 0, 0, 0) != 0:
        was = -1  # refused: nothing to restore
    try:
        yield
    finally:
        if was == 0:
            prctl(PR_SET_THP_DISABLE, 0, 0, 0, 0)
