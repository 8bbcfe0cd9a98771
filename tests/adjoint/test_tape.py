"""The tape a gradient reverses (``adjoint.tape``, ``adjoint.reverse``): what a step taken again
writes on it, what of it runs and what it copies, and what it refuses."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.adjoint import HeightMisfit, gradient
from swe_sphere.adjoint.gradient import step_adjoint
from swe_sphere.adjoint.tape import Combine, Evaluate, Smooth, combination
from swe_sphere.core.errors import ArgumentError
from swe_sphere.kernels import blas

import taylor


def _reversed_once(stepper: str, k: int = 3):
    """A step adjoint of TC5 ne 2 by ``stepper`` that has reversed step k twice (its tape analysed)."""
    model, st, x0 = taylor.setup(stepper)
    adjoint = step_adjoint(model, st)
    rows = 3 * (1 + len(st.carried_arrays()))
    x = wp.array(np.tile(x0, (rows // 3, 1)), dtype=taylor.f64)
    for _ in range(2):
        adjoint.reverse(x, wp.zeros((rows, model.N), dtype=taylor.f64), k)
    return adjoint


def test_a_runge_kutta_step_taken_again_runs_up_to_its_last_f_and_copies_what_it_overwrites():
    """rk4's step on the tape: four F evaluations and the ∇⁴. Its last F writes x(n+1) alone,
    which no F reads, so neither it nor the ∇⁴ runs when a step is taken again; the second F's
    state (a stage buffer the third rewrites) and the third's (which it writes itself) are copied,
    the first's (x(n), no longer overwritten) and the last's are read where they stand."""
    tape = _reversed_once("rk4").tape
    kinds = [type(op) for op in tape.ops]
    assert kinds == [Evaluate, Evaluate, Evaluate, Evaluate, Smooth]
    structure, runs, copies = tape.expected
    assert runs == (True, True, True, False, False)
    assert copies == (False, True, True, False, False)
    assert [op.state is op.x for op in tape.ops[:4]] == [True, False, False, True]


def test_leapfrog_s_step_taken_again_runs_nothing_but_reads_its_f_where_it_stands():
    """Leapfrog (k ≥ 1): F(x(n)) into x̃(n−1) + 2Δt F, the ∇⁴, the Robert–Asselin filter and the
    copy into x: no F reads any of their results, so a step taken again runs none of them, and its
    one F's state is x(n) itself."""
    tape = _reversed_once("leapfrog").tape
    assert [type(op) for op in tape.ops] == [Evaluate, Smooth, Combine, Combine]
    assert tape.expected[1] == (False, False, False, False)
    assert tape.ops[0].state is tape.ops[0].x


def test_the_tape_reads_blas_combinations_and_refuses_other_pointwise_kernels():
    a, b, out = (wp.zeros((3, 4), dtype=taylor.f64) for _ in range(3))
    assert combination(blas.axpby, (taylor.f64(2.0), a, taylor.f64(-1.0), b, out)) == (out, ((2.0, a), (-1.0, b)))
    with pytest.raises(ArgumentError, match="no gradient through the pointwise kernel"):
        combination(blas.row_totals, (a, out))


def test_a_stepper_whose_step_the_tape_cannot_read_is_refused_before_it_runs():
    _, _, x0 = taylor.setup()
    for name in ("implicit", "epi2"):
        with pytest.raises(ValueError, match="gradients need an explicit stepper"):
            gradient(taylor.tc5(name), 1, HeightMisfit(x0[2]))
