"""Butcher tables: their options, checks and order conditions.

A table (a scene's ``[tableau]``, or a built-in one of ``tables``) gives an explicit Runge–Kutta table (A, b, c)
or an IMEX additive Runge–Kutta pair (A_E, b_E, A_I, b_I, c), entries as
numbers or exact fractions written as strings ("1/6",
"1471266399579/7840856788654"), with the ``order`` it claims and a ``name``
(and ``description``) that the run file and ``swe-sphere list`` show. Checked
once, at load (``parse``): the shapes; A (A_E) strictly lower triangular; A_I
lower triangular (diagonally implicit: a_ii = 0 allowed, an explicit stage);
every row sum equal to c; and the order conditions up to the claimed order,
Φ(t) = 1/γ(t) for every rooted tree t of at most that many vertices (Butcher
2016, *Numerical Methods for ODEs*, §31; the 8 conditions of order 4 for an
explicit table), for a pair over the trees whose inner vertices are coloured
by the part whose matrix reaches them and whose root picks b_E or b_I
(Kennedy & Carpenter 2003, Appl. Numer. Math. 44, 139, §3: with one c the
leaves need no colour), which gives the coupling conditions. Each to
``TOL`` (coefficients printed to ten digits pass). In exact rational
arithmetic from the entries as written (a number as the binary value it is).

The engine (``runge_kutta``) steps an explicit table through its
``stage_plan.stage_form`` (each stage's combinations written by the DSS of its RHS) and
a pair through the IMEX stages, one Helmholtz solve per implicit stage.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..model.helmholtz import HelmholtzOptions
from .tables import EXPLICIT, IMEX, IMEX_PAIRS

TOL = 1e-9  # order conditions and row sums hold to this (rational entries exactly)
MAX_ORDER = 6
PARTS = ("A", "b", "c", "A_E", "b_E", "A_I", "b_I", "b_hat", "b_hat_E", "b_hat_I")


def frozen_table(value):
    """A TOML array (lists, or tuples) as nested tuples."""
    return tuple(frozen_table(v) for v in value) if isinstance(value, (list, tuple)) else value


@dataclass(frozen=True)
class TableauOptions(HelmholtzOptions):
    """Scene table ``[tableau]``: ``name`` and ``description`` of the table (strings,
    shown by the run file and ``swe-sphere list``), the ``order`` it claims (1..6),
    an explicit table ``A`` (s × s), ``b``, ``c`` (s) or an IMEX pair ``A_E``,
    ``b_E``, ``A_I``, ``b_I`` and ``c``, entries numbers or fractions as strings
    ("1/6"); an embedded pair adds the weights ``b_hat`` (an IMEX pair ``b_hat_E`` and
    ``b_hat_I``, equal in Kennedy & Carpenter's) of a solution of ``embedded_order``
    (1..order − 1), whose difference from x(n+1) is the step's error estimate;
    for a pair also the Helmholtz solve's ``tol``, ``maxiter``,
    ``mean_depth``, ``precision`` and ``guess_history`` (as ``[imex]``'s). No table at all: the classical RK4 table.
    Raises ValueError naming the entry or the failing condition (``parse``)."""

    name: str = ""
    description: str = ""
    order: int = 0
    A: tuple = ()
    b: tuple = ()
    c: tuple = ()
    A_E: tuple = ()
    b_E: tuple = ()
    A_I: tuple = ()
    b_I: tuple = ()
    b_hat: tuple = ()
    b_hat_E: tuple = ()
    b_hat_I: tuple = ()
    embedded_order: int = 0

    def __post_init__(self):
        for key in PARTS:  # a table read back from JSON (a restart file's scene) holds lists
            object.__setattr__(self, key, frozen_table(getattr(self, key)))
        if not self.name and not self.order and not any(getattr(self, key) for key in PARTS):
            for key, value in EXPLICIT["rk4"].items():  # the default: the classical RK4 table
                object.__setattr__(self, key, value)
        super().__post_init__()
        parse(self)


@dataclass(frozen=True)
class Table:
    """A checked table in exact arithmetic: A_E, b_E (the explicit part; an explicit
    table's A, b), A_I, b_I (None for an explicit table), c, order; an embedded pair's
    b̂ (``bh_E``, ``bh_I``: None without one) and ``embedded_order`` (0 without)."""

    A_E: tuple
    b_E: tuple
    A_I: tuple | None
    b_I: tuple | None
    c: tuple
    order: int
    bh_E: tuple | None = None
    bh_I: tuple | None = None
    embedded_order: int = 0

    @property
    def imex(self) -> bool:
        return self.A_I is not None

    @property
    def estimate(self) -> tuple | None:
        """The error estimate's weights (b_E − b̂_E, b_I − b̂_I; an explicit table's b_I
        None), exact: e = Δt Σ_j (d_E,j S(Y_j) + d_I,j L Y_j); None without a b̂."""
        if self.bh_E is None:
            return None
        d = lambda b, bh: None if b is None else tuple(x - y for x, y in zip(b, bh))  # noqa: E731
        return d(self.b_E, self.bh_E), d(self.b_I, self.bh_I)

    def floats(self):
        """(A_E, b_E, A_I, b_I, c) as float arrays (an explicit table: A_I, b_I None)."""
        arr = lambda t: None if t is None else np.array(t, dtype=float)  # noqa: E731
        return tuple(arr(t) for t in (self.A_E, self.b_E, self.A_I, self.b_I, self.c))


def _square(p: list) -> list:
    """The coefficients of the square of the polynomial with coefficients ``p`` (lowest first)."""
    return [
        sum(p[i] * p[k - i] for i in range(max(0, k - len(p) + 1), min(k, len(p) - 1) + 1))
        for k in range(2 * len(p) - 1)
    ]


def _stability_coefficients(A, b) -> list[Fraction]:
    """c_k = bᵀ A^(k−1) 1 (c₀ = 1), k = 0..s, exactly: R(z) = Σ c_k z^k, the stability polynomial
    of the explicit table (A, b)."""
    A = [[Fraction(a) for a in row] for row in A]
    coeffs, power = [Fraction(1)], [Fraction(1)] * len(b)
    for _ in range(len(b)):
        coeffs.append(sum(Fraction(bj) * pj for bj, pj in zip(b, power)))
        power = [sum(a * p for a, p in zip(row, power)) for row in A]
    return coeffs


def real_axis_limit(A, b) -> float:
    """The largest x ≥ 0 with |R(−x')| ≤ 1 for every 0 ≤ x' ≤ x (R the stability polynomial of
    the explicit table (A, b), ``imaginary_axis_limit``'s): the ν Δt λ of a damping term (an
    eigenvalue −λ of the right-hand side, the ∇⁴'s) the table steps without growth (Hairer & Wanner
    1996, §IV.2). 2 for forward Euler, ≈ 2.51 for SSP-RK3, 2.79 for RK4, 5.15 for SSPRK(4,3);
    at most 2s² for s stages (the Chebyshev bound). To 1e-9."""
    polynomial = np.polynomial.Polynomial([float(c) for c in _stability_coefficients(A, b)])
    s = len(b)
    xs = np.linspace(0.0, 2.0 * s * s + 1.0, 2000 * (2 * s * s + 1) + 1)
    grows = np.abs(polynomial(-xs)) > 1.0 + 1e-12
    if not grows.any():
        return float(xs[-1])
    lo, hi = xs[int(np.argmax(grows)) - 1], xs[int(np.argmax(grows))]
    while hi - lo > 1e-10:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if abs(polynomial(-mid)) <= 1.0 + 1e-12 else (lo, mid)
    return float(lo)


def imaginary_axis_limit(A, b) -> float:
    """The largest y ≥ 0 with |R(iy')| ≤ 1 for every 0 ≤ y' ≤ y, where
    R(z) = 1 + Σ_k z^k bᵀ A^(k−1) 1 is the stability polynomial of the explicit table
    (A, b) (s × s and s entries, numbers or ``Fraction``s): the Courant number of a
    wave (an eigenvalue iω of the right-hand side, ωΔt = y) the table steps without
    growth (Hairer & Wanner 1996, *Solving ODEs II*, §IV.2). 0 where no stretch of the
    axis is stable (forward Euler; every two-stage second-order table, whose
    |R(iy)|² = 1 + y⁴/4); √3 for every three-stage third-order table, 2√2 for the
    four-stage fourth-order ones. To 1e-9."""
    s = len(b)
    coeffs = _stability_coefficients(A, b)
    # |R(iy)|² − 1 = Re² + Im² − 1, a polynomial in y: stable near 0 iff its lowest term is negative
    re = [c * (-1) ** (k // 2) if k % 2 == 0 else 0 for k, c in enumerate(coeffs)]
    im = [c * (-1) ** (k // 2) if k % 2 else 0 for k, c in enumerate(coeffs)]
    growth = [x + y for x, y in zip(_square(re), _square(im))]
    growth[0] -= 1
    # a coefficient within TOL of 0 is 0: a table given to 30 digits (rdpk3sp35) misses its
    # order conditions, and so the zeros they make here, by ~1e-30
    lowest = next((g for g in growth[1:] if abs(g) > TOL), Fraction(0))
    if lowest >= 0:
        return 0.0
    polynomial = np.polynomial.Polynomial([float(g) for g in growth])
    # scanned past s − 1, the most s stages reach (Vichnevetsky 1983), then the first crossing bisected
    ys = np.linspace(0.0, s + 1.0, 4000 * (s + 1) + 1)
    first = int(np.argmax(polynomial(ys) > 1e-12))  # 1 ≤ first: stable just past 0 (checked above)
    lo, hi = ys[first - 1], ys[first]
    while hi - lo > 1e-10:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if polynomial(mid) <= 1e-12 else (lo, mid)
    return lo


def _text(q: Fraction) -> str:
    """An entry for a message: "1/6" for a small denominator, else ten digits."""
    return str(q) if q.denominator <= 10**4 else f"{float(q):.10g}"


def table_entry(value, where: str) -> Fraction:
    """A table entry (a finite number, or a fraction as a string: "1/6") as a Fraction;
    ValueError naming ``where`` otherwise."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if math.isfinite(value):
            return Fraction(value)
    elif isinstance(value, str):
        try:
            return Fraction(value.strip())
        except (ValueError, ZeroDivisionError):
            pass
    raise ValueError(f'{where} = {value!r} is not a number or a fraction such as "1/6"')


def _vector(o, key: str, s: int | None) -> tuple:
    value = getattr(o, key)
    if not isinstance(value, tuple) or not value:
        raise ValueError(f"{key} must be a non-empty array of numbers (got {value!r})")
    if s is not None and len(value) != s:
        raise ValueError(f"{key} has {len(value)} entries, not {s} (one per stage)")
    return tuple(table_entry(v, f"{key} entry {i + 1}") for i, v in enumerate(value))


def _matrix(o, key: str) -> tuple:
    rows = getattr(o, key)
    if not isinstance(rows, tuple) or not rows:
        raise ValueError(f"{key} must be a non-empty array of rows (got {rows!r})")
    s = len(rows)
    for i, row in enumerate(rows):
        if not isinstance(row, tuple):
            raise ValueError(f"{key} row {i + 1} must be an array of numbers (got {row!r})")
        if len(row) != s:
            raise ValueError(
                f"{key} row {i + 1} has {len(row)} entries, not {s}: {key} must be square (s x s, {s} rows)"
            )
    return tuple(
        tuple(table_entry(v, f"{key} entry ({i + 1},{j + 1})") for j, v in enumerate(row)) for i, row in enumerate(rows)
    )


def parse(o) -> Table:
    """The checked ``Table`` of ``TableauOptions`` ``o``; ValueError (one line, naming the
    key, entry or condition) for a missing or extra part, a ragged or non-square
    matrix, an entry that is not a number or fraction, an explicit part not strictly
    lower triangular, an implicit part not lower triangular, a row sum other than c,
    or a failing order condition."""
    given = [key for key in PARTS if getattr(o, key)]
    explicit, pair = {"A", "b", "b_hat"} & set(given), {"A_E", "b_E", "A_I", "b_I", "b_hat_E", "b_hat_I"} & set(given)
    if explicit and pair:
        raise ValueError(
            f"give A, b (an explicit table) or A_E, b_E, A_I, b_I (an IMEX pair), not both (got {', '.join(given)})"
        )
    needed = ("A_E", "b_E", "A_I", "b_I", "c") if pair else ("A", "b", "c")
    for key in needed:
        if key not in given:
            kind = (
                "an IMEX pair needs A_E, b_E, A_I, b_I and c"
                if pair
                else "an explicit table needs A, b and c (an IMEX pair A_E, b_E, A_I, b_I and c)"
            )
            raise ValueError(f"{key} is missing: {kind}")
    if not o.name.strip():
        raise ValueError("name is missing: name the table (the run file and `swe-sphere list` show it)")
    if not 1 <= o.order <= MAX_ORDER:
        raise ValueError(
            f"order must be the order the table claims, 1..{MAX_ORDER} (got {o.order}): its order conditions are checked"
        )
    A_E = _matrix(o, "A_E" if pair else "A")
    s = len(A_E)
    b_E = _vector(o, "b_E" if pair else "b", s)
    c = _vector(o, "c", s)
    A_I = _matrix(o, "A_I") if pair else None
    b_I = _vector(o, "b_I", s) if pair else None
    for key, A in (("A_E" if pair else "A", A_E), ("A_I", A_I)):
        if A is None:
            continue
        implicit = key == "A_I"
        for i, j in itertools.product(range(s), repeat=2):
            if A[i][j] and (j > i or (j == i and not implicit)):
                why = (
                    "the implicit part must be diagonally implicit (lower triangular)"
                    if implicit
                    else "an explicit part is strictly lower triangular"
                    + ("" if pair else " (an implicit part goes in A_I of an IMEX pair)")
                )
                raise ValueError(
                    f"{key} entry ({i + 1},{j + 1}) = {_text(A[i][j])} is {'above' if j > i else 'on'} the diagonal: {why}"
                )
        for i in range(s):
            if abs(sum(A[i]) - c[i]) > TOL:
                raise ValueError(f"{key} row {i + 1} sums to {_text(sum(A[i]))}, not c entry {i + 1} = {_text(c[i])}")
    bh_E, bh_I = _embedded(o, pair, s)
    table = Table(A_E, b_E, A_I, b_I, c, o.order, bh_E, bh_I, o.embedded_order)
    _check_order(table, table.b_E, table.b_I, table.order)
    if bh_E is not None:
        _check_order(table, bh_E, bh_I, table.embedded_order, "b_hat")
    return table


BUILT_IN = {**EXPLICIT, **IMEX, **IMEX_PAIRS}  # the built-in tables' parts, by key


@functools.cache
def built_in_table(key: str) -> Table:
    """The checked ``Table`` of the built-in ``key`` (of ``BUILT_IN``), parsed and checked when
    first asked, then kept: not at import, where every process's start paid for all of them
    (0.06-0.18 s) and a run steps one or two; KeyError for another key."""
    return parse(TableauOptions(**BUILT_IN[key]))


def _embedded(o, pair: bool, s: int) -> tuple:
    """(b̂_E, b̂_I) of ``o`` (an explicit table's b̂_I None), or (None, None) without; ValueError
    for a b̂ without ``embedded_order`` or the other way round, half a pair's b̂, or an
    embedded order not below the order."""
    keys = ("b_hat_E", "b_hat_I") if pair else ("b_hat",)
    given = [key for key in keys if getattr(o, key)]
    if not given and not o.embedded_order:
        return None, None
    if len(given) < len(keys):
        missing = next(key for key in keys if key not in given)
        raise ValueError(
            f"{missing} is missing: an embedded pair gives "
            + (" and ".join(keys) if pair else "b_hat")
            + " with its embedded_order"
        )
    if not 1 <= o.embedded_order < o.order:
        raise ValueError(
            f"embedded_order must be the order b_hat claims, 1..order − 1 = {o.order - 1} (got {o.embedded_order}): "
            "its order conditions are checked"
        )
    bh = [_vector(o, key, s) for key in keys]
    return bh[0], (bh[1] if pair else None)


# -- order conditions ------------------------------------------------------------------
LEAF = "c"


@functools.cache
def _subtrees(n: int, colours: tuple) -> tuple:
    """The non-root rooted trees of n vertices: LEAF, or (colour, children) with the
    children a sorted tuple (the colour: the matrix that reaches the vertex)."""
    if n == 1:
        return (LEAF,)
    return tuple((colour, forest) for colour in colours for forest in _forests(n - 1, colours))


@functools.cache
def _forests(n: int, colours: tuple, smallest: int = 0) -> tuple:
    """Multisets of non-root trees of n vertices in all, as tuples in the order of
    ``_catalogue`` from position ``smallest`` on (each multiset once)."""
    if n == 0:
        return ((),)
    out = []
    for index, (size, tree) in enumerate(_catalogue(n, colours)):
        if index >= smallest and size <= n:
            out += [(tree, *rest) for rest in _forests(n - size, colours, index)]
    return tuple(out)


@functools.cache
def _catalogue(n: int, colours: tuple) -> tuple:
    return tuple((k, t) for k in range(1, n + 1) for t in _subtrees(k, colours))


def _density(tree) -> int:
    if tree == LEAF:
        return 1
    return (1 + sum(_size(t) for t in tree[1])) * math.prod(_density(t) for t in tree[1])


def _size(tree) -> int:
    return 1 if tree == LEAF else 1 + sum(_size(t) for t in tree[1])


def _weights(forest, table: Table, c) -> list:
    """∏ over the children of their stage vectors, elementwise (ones for none)."""
    out = [Fraction(1)] * len(c)
    for tree in forest:
        if tree == LEAF:
            v = c
        else:
            A = table.A_E if tree[0] == "E" else table.A_I
            w = _weights(tree[1], table, c)
            v = [sum(a * x for a, x in zip(row, w)) for row in A]
        out = [x * y for x, y in zip(out, v)]
    return out


def _label(forest, sub: bool) -> str:
    """The product of the children's vectors, written as in Butcher's tables: c², Ac, (c∘Ac)."""
    factors = {}
    for tree in forest:
        text = "c" if tree == LEAF else "A" + (f"_{tree[0]} " if sub else "") + _label(tree[1], sub)
        factors[text] = factors.get(text, 0) + 1
    power = str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹")
    parts = [
        (t if t == "c" or k == 1 else f"({t})") + (str(k).translate(power) if k > 1 else "") for t, k in factors.items()
    ]
    return parts[0] if len(parts) == 1 else "(" + "∘".join(parts) + ")"


def conditions(order: int, imex: bool):
    """The order conditions up to ``order``, lowest order first: (order, root colour,
    children, 1/γ) for each rooted tree (colours "E" and "I" for a pair)."""
    colours = ("E", "I") if imex else ("E",)
    for p in range(1, order + 1):
        for root in colours:
            for forest in _forests(p - 1, colours):
                yield p, root, forest, Fraction(1, _density(("root", forest)))


def _check_order(table: Table, b_E, b_I, order: int, weights: str = "b") -> None:
    """ValueError naming the first order condition up to ``order`` that the weights
    (b_E, b_I) of ``table``'s stages fail (``weights``: "b", or "b_hat" for the embedded ones)."""
    claim = "order" if weights == "b" else "embedded_order"
    for p, root, forest, target in conditions(order, table.imex):
        b = b_E if root == "E" else b_I
        value = sum(x * y for x, y in zip(b, _weights(forest, table, table.c)))
        if abs(value - target) > TOL:
            sub = f"_{root}" if table.imex else ""
            name = f"Σ{weights}{sub}" if not forest else f"{weights}{sub}·{_label(forest, table.imex)}"
            raise ValueError(
                f"{claim} = {order} claimed, but the order-{p} condition {name} = {target} fails (it is {_text(value)})"
            )


class _Tables(Mapping):
    """The built-in tables by key (``butcher.built_in_table``: each checked when first read, not
    at import)."""

    def __getitem__(self, key: str) -> Table:
        return built_in_table(key)

    def __iter__(self) -> Iterator[str]:
        return iter(BUILT_IN)

    def __len__(self) -> int:
        return len(BUILT_IN)


TABLES = _Tables()
