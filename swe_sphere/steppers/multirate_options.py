"""What a scene says of the multirate steppers (``multirate``): the options of
``[split_explicit]`` and ``[mri]`` and the check of a multirate table, ``parse_mri``, which
turns it into the inner solves' coefficients and the explicit Runge–Kutta table of its slow
part."""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..model.gravity_wave import check_mean_depth
from .butcher import TableauOptions, frozen_table, table_entry
from .tables import MULTIRATE

INNER = ("fbrk32", "ssprk3", "rk4")


def check_substeps(substeps, fast_courant) -> None:
    """ValueError 'substeps must be ...' unless an integer ≥ 1 or "auto", 'fast_courant
    must be ...' unless > 0."""
    if substeps != "auto" and (isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1):
        raise ValueError(f'substeps must be an integer >= 1 or "auto" (got {substeps!r})')
    if isinstance(fast_courant, bool) or not isinstance(fast_courant, (int, float)) or not fast_courant > 0:
        raise ValueError(f"fast_courant must be > 0 (got {fast_courant!r})")


def substeps_label(options) -> str:
    """'n=12', or 'n=auto (fast Courant 0.6)'."""
    if options.substeps == "auto":
        return f"n=auto (fast Courant {options.fast_courant:g})"
    return f"n={options.substeps}"


@dataclass(frozen=True)
class SplitExplicitOptions:
    """Scene table ``[split_explicit]`` (see ``SplitExplicit``)."""

    substeps: int | str = "auto"
    fast_courant: float = 0.6
    divergence_damping: float = 0.1
    mean_depth: float = 0.0

    def __post_init__(self):
        check_substeps(self.substeps, self.fast_courant)
        if not 0 <= self.divergence_damping < 1:
            raise ValueError(f"divergence_damping must be in [0, 1) (got {self.divergence_damping})")
        check_mean_depth(self.mean_depth)


# -- multirate infinitesimal tables ----------------------------------------------------
@dataclass(frozen=True)
class MriOptions:
    """Scene table ``[mri]`` (see ``Mri``): ``method`` (a built-in table of
    ``tables.MULTIRATE``), or a table of one's own: ``name``, ``description``, the
    ``order`` it claims, ``alpha``, ``beta``, ``gamma`` and ``beta1`` (s × s, entries
    numbers or fractions as strings; alpha, gamma and beta1 may be left out: zero); ``inner``,
    ``substeps``, ``fast_courant``, ``mean_depth``. Raises ValueError naming the option or entry (``parse_mri``)."""

    method: str = "mis4a"
    inner: str = "ssprk3"
    substeps: int | str = "auto"
    fast_courant: float = 1.0
    mean_depth: float = 0.0
    name: str = ""
    description: str = ""
    order: int = 0
    alpha: tuple = ()
    beta: tuple = ()
    gamma: tuple = ()
    beta1: tuple = ()

    def __post_init__(self):
        for key in MRI_PARTS:  # read back from JSON (a restart file's scene): lists
            object.__setattr__(self, key, frozen_table(getattr(self, key)))
        if self.method not in MULTIRATE:
            raise ValueError(f"method must be one of {', '.join(MULTIRATE)} (got {self.method!r})")
        if self.inner not in INNER:
            raise ValueError(f"inner must be one of {', '.join(INNER)} (got {self.inner!r})")
        check_substeps(self.substeps, self.fast_courant)
        check_mean_depth(self.mean_depth)
        parse_mri(self)

    def table(self) -> dict:
        """The table's entries: the scene's own if it gives one, else ``method``'s."""
        own = {key: getattr(self, key) for key in MRI_PARTS if getattr(self, key)}
        if not own and not self.name and not self.order:
            return dict(MULTIRATE[self.method])
        return {"name": self.name, "description": self.description, "order": self.order, **own}


MRI_PARTS = ("alpha", "beta", "gamma", "beta1")


@dataclass(frozen=True)
class MriTable:
    """A checked multirate table: alpha, beta, gamma, beta1 (s × s float arrays), d (s,)
    the solves' spans in Δt, c (s,) the stages' times in Δt (those of the slow table),
    and the slow part's Butcher table (``TableauOptions``)."""

    alpha: np.ndarray
    beta: np.ndarray
    gamma: np.ndarray
    beta1: np.ndarray
    d: np.ndarray
    c: tuple
    slow: TableauOptions


def _square(t: dict, key: str, s: int | None) -> list:
    rows = frozen_table(t.get(key, ()))
    if s is not None and not rows:  # alpha, gamma, beta1 left out: zero
        return [[Fraction(0)] * s for _ in range(s)]
    if not isinstance(rows, tuple) or not rows or not all(isinstance(r, tuple) for r in rows):
        raise ValueError(f"{key} must be a non-empty array of rows (got {rows!r})")
    if len(rows) != (s or len(rows)) or any(len(r) != len(rows) for r in rows):
        shape = f"{len(rows)} rows of {', '.join(str(len(r)) for r in rows)} entries"
        raise ValueError(
            f"{key} must be square (got {shape})" if s is None else f"{key} must be {s} x {s}, as beta (got {shape})"
        )
    s = len(rows)
    out = [[table_entry(v, f"{key} entry ({i + 1},{j + 1})") for j, v in enumerate(r)] for i, r in enumerate(rows)]
    for i in range(s):
        for j in range(i + 1, s):
            if out[i][j]:
                raise ValueError(f"{key} entry ({i + 1},{j + 1}) is above the diagonal: solve r uses stages 1..r only")
    return out


def parse_mri(o: MriOptions) -> MriTable:
    """The checked table of ``o``; ValueError (one line) for a missing name or order, a
    matrix that is not s × s lower triangular, an entry that is not a number, a solve of
    span d_r = Σ_j β_rj ≤ 0, or a slow part (the method with L = 0, an explicit
    Runge–Kutta table) that fails its claimed order's conditions (``butcher.parse``).

    Without a fast part (L = 0) a multirate table is an explicit Runge–Kutta table of the
    slow part (Y_{r+2} − x(n) = Σ_j (α + γ)_rj (Y_{j+1} − x(n)) + Δt Σ_j (β + β¹/2)_rj
    S(Y_{j+1})), checked against the order the table claims by ``butcher.parse``, the one
    engine's order conditions (necessary, not sufficient: the coupling has conditions of its
    own, which the built-in tables meet at their stated orders; measured in
    tests/steppers/test_multirate.py)."""
    t = o.table()
    if not str(t.get("name", "")).strip():
        raise ValueError("name is missing: name the table (the run file shows it)")
    beta = _square(t, "beta", None)
    s = len(beta)
    alpha, gamma, beta1 = (_square(t, key, s) for key in ("alpha", "gamma", "beta1"))
    d = [sum(row) for row in beta]
    for r, span in enumerate(d):
        if span <= 0:
            raise ValueError(
                f"beta row {r + 1} sums to {float(span):.6g}: each inner solve's span d = the row sum must be > 0"
            )
    # the slow part: Y_{r+2} − x(n) = Σ_j (α + γ)_rj (Y_{j+1} − x(n)) + Δt Σ_j (β + β¹/2)_rj F_{j+1}
    A = [[Fraction(0)] * s]
    for r in range(s):
        row = [beta[r][j] + beta1[r][j] / 2 for j in range(s)]
        for j in range(r + 1):
            row = [a + (alpha[r][j] + gamma[r][j]) * y for a, y in zip(row, A[j])]
        A.append(row)
    c = [sum(row) for row in A[:s]]
    slow = TableauOptions(
        name=str(t["name"]),
        description=str(t.get("description", "")),
        order=int(t.get("order", 0)),
        A=tuple(tuple(str(a) for a in row) for row in A[:s]),
        b=tuple(str(a) for a in A[s]),
        c=tuple(str(a) for a in c),
    )
    arr = lambda m: np.array([[float(v) for v in row] for row in m])  # noqa: E731
    return MriTable(
        arr(alpha), arr(beta), arr(gamma), arr(beta1), np.array([float(v) for v in d]), tuple(float(v) for v in c), slow
    )
