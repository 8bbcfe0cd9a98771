"""The state a run holds between steps (``ShallowWater.held``), and the one place it is read or
set in float64.

Under ``precision = "float32_state"`` (without ``compensated``: its default) the run holds the float32 state its
steps carry, u, v and h − H₀ (``kernels.departure``), from its first step to its last: a step
reads it and writes it in place and converts nothing. What reads it in float64 converts here: the
diagnostics and the files (``values``: the float64 state on the host), the operators the
diagnostics run and, with a filter or ν_div ≠ ν, the ∇⁴ on its steps (``float64``: a float64
copy on the device, one work array of the model; otherwise the ∇⁴ acts on the kept state in place:
``ShallowWater.hyperviscosity``), a state set from outside and a restart (``assign``: rounded once, or the
float32 bits as a restart file kept them). Otherwise (float64, "float32", and "float32_state"
compensated, whose compensation is the float64 state itself) the run holds the float64 state and
each of these is x itself. u, v and the tracers' rows are the same numbers in either form; only
h is shifted, and f64(y) + H₀ rounds back to y only where |y| ≥ 2⁻²⁹ H₀ or so, so a restart keeps
y's bits (``departure``)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import departure

f64 = wp.float64


class HeldState:
    """The state ``model`` holds between steps: its ``dtype`` (float64, or the model's
    ``state_dtype`` float32 when kept in it), and its conversions to and from float64 (states
    (rows, N) of the model's nodes; ``depth`` H₀ (m), the tendency's reference depth)."""

    def __init__(self, model):
        self.model = model
        kept = model.state_dtype is not f64 and not model.compensated
        self.dtype = model.state_dtype if kept else f64
        self.depth = model.tendency_arrays.depth
        self._work = None  # ``float64``'s device copy, made on first use

    @property
    def kept(self) -> bool:
        """Whether the run holds the float32 state (else the float64 one)."""
        return self.dtype is not f64

    def new(self, values: np.ndarray) -> wp.array2d:
        """A held state (rows, N) on the model's device from float64 host ``values`` (rows, N),
        its mass taken as the one to keep (``take_mass``)."""
        x = wp.array(self.rounded(values), dtype=self.dtype, device=self.model.device)
        self.take_mass(x)
        return x

    def rounded(self, values: np.ndarray) -> np.ndarray:
        """``values`` (rows, N float64: u, v, h, …) as the held state's numbers: themselves, or
        h − H₀ formed in float64 and every row rounded once to float32 (``to_departure``'s bits)."""
        values = np.asarray(values, dtype=np.float64)
        if not self.kept:
            return values
        y = values.copy()
        y[2] -= self.depth
        return y.astype(np.float32)

    def assign(self, x: wp.array2d, values: np.ndarray, departure: np.ndarray | None = None) -> None:
        """Set the held state x from float64 host ``values`` (rows, N); ``departure`` (N,), where a
        restart file kept them, the float32 state's h − H₀ as it was (its bits, not h's rounding)."""
        y = self.rounded(values)
        if self.kept and departure is not None:
            y[2] = np.asarray(departure, dtype=np.float32)
        x.assign(y)
        self.take_mass(x)

    def take_mass(self, x: wp.array2d) -> None:
        """A kept float32 state's mass, as it is set, taken as the mass its fixer keeps
        (``model.mass_fixer``; a restart's own put back after: ``members``): a step's uniform depth
        below float32's spacing is lost, so each step's start would drift, and a mass taken here
        rather than at the first step leaves a step's launches the same every step (a captured
        graph's). Nothing otherwise (a float64 state's fixer takes each step's start's)."""
        if self.kept and self.model.mass_fixer is not None:
            self.model.mass_fixer.measure(x)

    def departure(self, x: wp.array2d) -> np.ndarray | None:
        """The kept float32 state's h − H₀ (N,) as it is (a restart file's ``h_departure``), None
        for a float64 state."""
        return x.numpy()[2].copy() if self.kept else None

    def values(self, x: wp.array2d) -> np.ndarray:
        """The float64 state (rows, N) on the host of a state x: a float64 one's, or a float32
        one's f64(y) + (0, 0, H₀)."""
        a = x.numpy()
        if x.dtype is f64:
            return a
        a = a.astype(np.float64)
        a[2] += self.depth
        return a

    def float64(self, x: wp.array2d, once: bool = False) -> wp.array2d:
        """The float64 state of x on the device: a float64 x itself, or f64(y) + (0, 0, H₀)
        (``kernels.departure.from_departure``) in the model's one work array, overwritten by the
        next call; ``once``: in an array of its own, for one use (a diagnosis at an output time),
        neither kept nor recorded."""
        if x.dtype is f64:
            return x
        launches = self.model.launches
        if once:
            y = wp.empty(x.shape, dtype=f64, device=x.device)
            launches.lanes_launch(departure.from_departure, x, f64(self.depth), y).launch()
            return y
        if self._work is None or self._work.shape != x.shape:
            self._work = wp.zeros(x.shape, dtype=f64, device=x.device)
        launches.run_lanes(departure.from_departure, x, f64(self.depth), self._work)
        return self._work

    def store(self, x64: wp.array2d, x: wp.array2d) -> None:
        """The held x from its float64 copy x64 (``float64``'s, after the ∇⁴ on it): h − H₀
        rounded once to float32 (``kernels.departure.to_departure``)."""
        self.model.launches.run_lanes(departure.to_departure, x64, f64(self.depth), x)
