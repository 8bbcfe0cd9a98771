"""How an ensemble's members start (``Simulation``'s ``initial`` with ``members``): seeded noise in the
case's state (``Perturbation``), an ensemble's run file (``MemberFile``), or each member's own
case parameters, Ω, g or ν (``Variants``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..cases.tracers import with_tracers
from ..core.arguments import array_argument, band_argument, got, integer_argument, number_argument
from ..core.errors import ArgumentError, SceneError
from ..grid.cubed_sphere import CubedSphere
from ..io.run_file import member_states

ON_ROOT = object()  # ``start`` on the ranks > 0 when rank 0 alone holds the whole-grid start state (``read_on_root``)

# the highest spherical-harmonic degree a perturbation's band may name: far past any grid's
# resolution here (ne120 np4 resolves l ≈ 720), a typo beyond it
MAX_DEGREE = 2048


@dataclasses.dataclass(frozen=True)
class Perturbation:
    """Members that differ by seeded noise in the depth: member k starts from the case's
    initial state with h + ``amplitude``·ξ_k on the grid's unique nodes (every copy of a node the
    same, so the state stays continuous). ``amplitude`` in m (≥ 0), ``seed`` an integer ≥ 0.

    - ``degrees`` None (white noise): ξ_k standard normal, one draw a node, the N members' drawn as
      ``numpy.random.default_rng(seed).standard_normal((N, nunique))``.
    - ``degrees`` (l_min, l_max), integers 1 ≤ l_min ≤ l_max ≤ ``MAX_DEGREE``, l_max within what the
      run's grid resolves (``check_band``, as the run's members start): ξ_k a random field of
      the spherical harmonics of those degrees alone, each degree holding the same variance (its
      2l + 1 orthonormal coefficients' real and imaginary parts drawn N(0, 1/(2l + 1)), m = 0's
      real), summed at the nodes (``cases.reference.synthesis``) and scaled to an
      area-weighted RMS of 1 over the sphere: large-scale noise that the ∇⁴ does not damp in
      hours, as white noise's grid-scale part is. The members' coefficients are drawn as
      ``default_rng(seed).standard_normal((N, 2, nalm))``, healpy's (l, m) order."""

    amplitude: float
    seed: int = 0
    degrees: tuple | None = None

    def __post_init__(self):
        number_argument("perturbation amplitude", self.amplitude, "m", low=0.0)
        integer_argument("perturbation seed", self.seed, 0)
        object.__setattr__(self, "degrees", band_argument("perturbation degrees", self.degrees, MAX_DEGREE))

    def apply(self, grid: CubedSphere, state: np.ndarray, members: int) -> np.ndarray:
        """(members, 3, n): ``state`` (3, n) on ``grid``'s element-local nodes, perturbed."""
        out = np.repeat(state[None], members, axis=0)
        out[:, 2] += self.amplitude * self._noise(grid, members)[:, grid.gid]
        return out

    def _noise(self, grid: CubedSphere, members: int) -> np.ndarray:
        """(members, nunique) the ξ_k of the class doc: white, or a band's fields each of area-weighted RMS 1."""
        if self.degrees is None:
            return np.random.default_rng(self.seed).standard_normal((members, grid.first.size))
        from ..cases.reference import synthesis

        lo, hi = self.degrees
        m, l = np.triu_indices(hi + 1)  # healpy's order: m-major (m = 0 … hi, l = m … hi)
        std = np.where(l >= lo, 1.0 / np.sqrt(2 * l + 1), 0.0)
        z = np.random.default_rng(self.seed).standard_normal((members, 2, l.size))
        alm = std * (z[:, 0] + 1j * np.where(m > 0, z[:, 1], 0.0))
        lat, lon = grid.lat[grid.first], np.mod(grid.lon[grid.first], 2 * np.pi)
        xi = np.stack([synthesis(a, hi, lat, lon) for a in alm])
        rms = np.sqrt(np.sum(grid.area * xi**2, axis=1) / np.sum(grid.area))
        return xi / rms[:, None]


def check_band(degrees: tuple | None, scene, name: str) -> None:
    """``ArgumentError`` naming ``name`` (the key the band was given by) for a ``Perturbation``'s
    ``degrees`` (l_min, l_max) whose l_max passes what the grid of ``scene`` (a ``Scene``)
    resolves (``Scene.grid_degree``): its noise would alias onto the degrees the grid holds."""
    top = int(scene.grid_degree)
    if degrees is not None and degrees[1] > top:
        raise ArgumentError(
            f"{name} {degrees[0]},{degrees[1]}: the {scene.grid_text} grid resolves degrees up to about {top} "
            f"(2 ne (np - 1), its nodes along the equator over 2): give l_max <= {top}"
        )


@dataclasses.dataclass(frozen=True)
class MemberFile:
    """Members that start from an ensemble's run file (``Simulation.run`` with ``members``, ``swe-sphere run
    --members``): member k from the file's member k, its u, v, h at model day ``day`` (None:
    the file's last time) on the grid's unique nodes, as they were written (a run file that
    was not compressed gives the states' bits); each of the scene's tracers from the file's q of
    that name where it holds one (the run of an ensemble with that tracer), else from its
    [tracers] field. ``path`` a str or os.PathLike."""

    path: object
    day: float | None = None

    def apply(self, grid: CubedSphere, members: int, scene=None) -> np.ndarray:
        """(members, 3 + K, n) on ``grid``'s element-local nodes: u, v, h and the masses h·q of
        the K tracers of ``scene`` (a ``Scene``'s [tracers]; None: none), q the file's or the
        scene's field (``Scene.tracer_fields``). ``ArgumentError`` naming ``initial`` for a file
        that cannot be read, is not an ensemble's run file, holds another member count or grid,
        or not ``day`` (``io.run_file.member_states``)."""
        names = () if scene is None else tuple(name for name, _ in scene.tracers)
        states, held = member_states(self.path, self.day, members, grid.nunique, f"initial: {self.path}", names)
        states = states[..., grid.gid]
        if not names:
            return states
        q = [
            held[name][:, grid.gid] if name in held else np.broadcast_to(field(grid.lat, grid.lon), states[:, 2].shape)
            for name, field in zip(names, scene.tracer_fields(), strict=True)
        ]
        return np.concatenate([states, states[:, 2:3] * np.stack(q, axis=1)], axis=1)


# what a member's own model holds (``Variants.own_model``): its gravity and ∇⁴ coefficients
MODEL_KEYS = ("planet.gravity", "hyperviscosity.nu", "hyperviscosity.nu_div", "hyperviscosity.nu_s")


@dataclasses.dataclass(frozen=True)
class Variants:
    """Members that differ by their scene's values: ``values`` {key: a sequence of N values},
    member k's scene the ensemble's with each key at its k-th value, started from its own
    case's state; member k has the bits of the single run of its scene. The keys: a case's
    parameter ``case.<name>`` (what sets the initial state, e.g. Galewsky's ``hhat``, ``umax``
    or ``lat2``; the surface height hs must come out the same for every member),
    ``planet.omega`` (Ω, s⁻¹: the member's Coriolis parameter 2Ω sin φ, and its case's
    balance), and, each member then on a model of its own (``own_model``), ``planet.gravity``
    (g, m s⁻²; the case's balance too) and ``hyperviscosity.nu`` (m⁴ s⁻¹; ν_div and ν_s with it
    where the scene's equal its ν, as a scene file's defaults tie them), ``.nu_div``, ``.nu_s``.
    Other values (the radius, the grid, Δt) the members share: ``ArgumentError`` naming the
    key, as for values of another count or a case that refuses a parameter."""

    values: dict

    def __post_init__(self):
        if not isinstance(self.values, dict) or not self.values:
            raise ArgumentError(f"variants: values must be a dict of keys to N values (got {got(self.values)})")
        for key in self.values:
            if not (isinstance(key, str) and (key.startswith("case.") or key in ("planet.omega", *MODEL_KEYS))):
                raise ArgumentError(
                    f"variants: {key!r} cannot differ between members (per member: case.<parameter>, "
                    f"planet.omega, {', '.join(MODEL_KEYS)})"
                )

    @property
    def own_model(self) -> bool:
        """Whether the members need a model each (their g or ν differ: values the kernels take once)."""
        return any(key in MODEL_KEYS for key in self.values)

    def scenes(self, scene, members: int) -> tuple[list, list]:
        """The members' scenes (a ``Scene`` a member) and their cases (each scene's
        ``make_case``, made once: it checks the values). ``ArgumentError`` for a count of
        values other than ``members`` or a value the scene's case refuses."""
        for key, values in self.values.items():
            if np.ndim(values) != 1 or len(values) != members:
                raise ArgumentError(f"variants: {key} needs {members} values, one a member (got {got(values)})")
        return tuple(map(list, zip(*(self._scene(scene, k) for k in range(members)))))  # (scenes, cases)

    def _scene(self, scene, k: int) -> tuple:
        """Member k's scene (``scenes``), ``scene`` with each key at its k-th value, and its case."""
        value = {key: float(v[k]) if not key.startswith("case.") else v[k] for key, v in self.values.items()}
        params = {key[5:]: v for key, v in value.items() if key.startswith("case.")}
        planet = {**scene.planet, **{key[7:]: v for key, v in value.items() if key.startswith("planet.")}}
        nus = {key[15:]: v for key, v in value.items() if key.startswith("hyperviscosity.")}
        if "nu" in nus:  # ν_div and ν_s follow ν where the scene ties them
            nus = {**{name: nus["nu"] for name in ("nu_div", "nu_s") if getattr(scene, name) == scene.nu}, **nus}
        for key in MODEL_KEYS:
            if key in value and not (value[key] > 0 if key == "planet.gravity" else value[key] >= 0):
                bound = "> 0" if key == "planet.gravity" else ">= 0"
                raise ArgumentError(f"variants: member {k}: {key} must be {bound} (got {value[key]!r})")
        member = dataclasses.replace(scene, case_params={**scene.case_params, **params}, planet=planet, **nus)
        try:
            return member, member.make_case()
        except (ValueError, TypeError) as err:
            raise ArgumentError(f"variants: member {k}: {err}") from None

    def describe(self) -> str:
        """The values, as a run file's ``initial_states`` says them."""
        return "variants: " + "; ".join(f"{k} = {', '.join(f'{v:g}' for v in vs)}" for k, vs in self.values.items())


def asked(scene, members, start, given=None, required: bool = False) -> tuple[int | None, object, object]:
    """(N, start, given) of a run's members: ``members``, else the scene's [ensemble] ``members``,
    None where neither names them (a single run; ``ArgumentError`` where ``required``), and
    ``start`` (``Simulation``'s ``initial``), else the [ensemble]'s ``Perturbation`` where its
    amplitude is above 0, a perturbation's band checked within the grid's degrees
    (``check_band``); ``given`` (``Simulation``'s ``start``) checked as an array (3 + K, n) (K the
    scene's tracers). ``SceneError`` for members with a function or a ``given`` start;
    ``ArgumentError`` for a single run's ``start`` that is not a function, or given with ``given``."""
    table = scene.ensemble  # the scene's [ensemble] table, or None
    if members is None and table is None:
        if required:
            raise ArgumentError("members must be given, or the scene name them ([ensemble] members)")
        if start is not None and (given is not None or not callable(start)):
            raise ArgumentError(
                f"initial must be a function (lat, lon) -> (h, u, v), and not given with start (got {got(start)})"
            )
        if given is not None and given is not ON_ROOT:
            # the grid's columns: ``distribute``; a row for each tracer's mass after u, v, h
            given = array_argument("start", given, (3 + len(scene.tracers), None), "m s⁻¹ and m")
        return None, start, given
    members = integer_argument("members", table["members"] if members is None else members, 1)
    perturbed = start is None and table is not None and table["perturbation"] > 0
    start = Perturbation(table["perturbation"], table["seed"], table.get("degrees")) if perturbed else start
    if isinstance(start, Perturbation):  # its band within the grid's degrees, named as it was given
        check_band(start.degrees, scene, "ensemble.degrees" if perturbed else "initial: perturbation degrees")
    if callable(start) or given is not None:
        raise SceneError(
            "initial: an [ensemble]'s members start from its perturbation, or an array, a Perturbation, a "
            "MemberFile or Variants (not a function, nor a start)"
        )
    return members, start, None


def initial_states(initial, grid: CubedSphere, case, members: int, cases=None, scene=None) -> np.ndarray:
    """(N, 3 + K, n) float64 the members' starts from ``initial`` (``Simulation``'s with ``members``: None, an
    array, a ``Perturbation``, a ``MemberFile`` or ``Variants``, whose members' ``cases`` these are) on
    ``grid`` from ``case``'s state, checked (``checked_states``): each member's u, v, h with a row of
    mass h·q for each of the K tracers of ``scene`` (its [tracers]; None: none), q its
    ``tracer_fields()`` for every member (``cases.tracers.with_tracers``, as a single run's start),
    a ``MemberFile``'s q where the file holds it, or an array's own rows hq where it gives them
    ((N, 3 + K, n): a restart file's). ``ArgumentError``
    naming ``initial`` for another kind or shape, or Variants whose surface heights differ."""
    nq = 0 if scene is None else len(scene.tracers)
    if initial is None or isinstance(initial, Perturbation):
        state = np.stack(case.initial(grid.lat, grid.lon))
        states = np.repeat(state[None], members, axis=0) if initial is None else initial.apply(grid, state, members)
    elif isinstance(initial, MemberFile):
        states = initial.apply(grid, members, scene)
    elif isinstance(initial, Variants):
        hs = case.hs(grid.lat, grid.lon)
        for k, member in enumerate(cases):
            if not np.array_equal(member.hs(grid.lat, grid.lon), hs):
                raise ArgumentError(f"variants: member {k}'s surface height hs differs (the members share hs)")
        states = np.stack([np.stack(member.initial(grid.lat, grid.lon)) for member in cases])
    elif isinstance(initial, np.ndarray | list | tuple):
        rows = 3 + nq if nq and np.shape(initial)[1:2] == (3 + nq,) else 3  # with the tracers' masses, or without
        states = array_argument("initial", initial, (members, rows, grid.nnodes), "m s⁻¹ and m")
    else:
        raise ArgumentError(
            "initial must be None, an array (members, 3, nnodes), a Perturbation, a MemberFile or Variants "
            f"(got {got(initial)})"
        )
    states = checked_states(states, case, "initial", range(members))
    if states.shape[1] == 3 + nq:
        return states
    fields = scene.tracer_fields()
    return np.stack([with_tracers(state, fields, grid.lat, grid.lon) for state in states])


class MembersAlike(UserWarning):
    """Members that start alike and step alike (``stay_alike``): they stay alike, their spread 0 m."""


def stay_alike(states: np.ndarray, initial) -> bool:
    """Whether the members started from ``states`` (N, 3, n) by ``initial`` (``initial_states``'s)
    stay alike: N > 1, every member's state the first's to the bit and its scene the first's
    (``Variants`` each of whose keys takes one value), so that each step keeps their bits the same."""
    if len(states) < 2 or not (states == states[0]).all():
        return False
    return not isinstance(initial, Variants) or all(all(v == vs[0] for v in vs) for vs in initial.values.values())


def alike_line(members: int) -> str:
    """The warning of ``members`` that stay alike (``stay_alike``), as Python and the command line give it."""
    return (
        f"the {members} members start alike (the same state to the bit, the same scene), so they stay alike "
        "and their spread is 0 m"
    )


def checked_states(states: np.ndarray, case, name: str, members) -> np.ndarray:
    """``states`` (M, 3, n) of ``members`` (their indices, M of them), refused (``ArgumentError``
    naming ``name`` and the member) where not finite or where a member's h ≤ 0 and h is
    ``case``'s depth."""
    if not np.isfinite(states).all():
        raise ArgumentError(f"{name}: a member's state is not finite")
    if case.h_is_depth and len(states):
        low = states[:, 2].min(axis=1)
        if np.any(low <= 0):
            k = int(np.argmax(low <= 0))
            raise ArgumentError(f"{name}: member {members[k]}'s depth h is <= 0 (min {low[k]:.4g} m)")
    return states


def described(initial) -> str:
    """The members' start in words, as a run file's ``initial_states`` says it."""
    if isinstance(initial, Perturbation):
        d = initial.degrees
        kind = "white noise" if d is None else f"noise in spherical-harmonic degrees {d[0]} to {d[1]}"
        return f"perturbed: h + {initial.amplitude:g} m {kind}, seed {initial.seed}"
    if isinstance(initial, MemberFile):
        return f"from {initial.path}" + ("" if initial.day is None else f" at day {initial.day:g}")
    return "the case's" if initial is None else initial.describe() if isinstance(initial, Variants) else "given"
