"""Lanczos low-pass filter in time (Duchon 1979), for the balanced part of a run.

A run's state sampled every ``every_hours`` over a window of ± ``half_window_days``
around a target day is averaged with Lanczos weights; periods shorter than
``period_days`` (the impulsive start's gravity waves on TC5: 8–33 h) are removed
and the slow, balanced flow is kept. Applied alike to a run and to its same-grid
small-Δt reference, the l2 of the filtered difference measures the error of the
balanced flow alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def lanczos_weights(cutoff: float, n: int) -> np.ndarray:
    """The 2n + 1 Lanczos low-pass weights w_{-n..n} (Duchon 1979, eqs. 2 and 3, with
    the sigma factor sin(πk/n)/(πk/n), so w_{±n} = 0), normalized to sum 1 (a
    constant passes unchanged). ``cutoff``: the half-power frequency in cycles per
    sample interval, 0 < cutoff < 0.5; ``n`` ≥ 1. Raises ``ValueError`` otherwise."""
    if not 0.0 < cutoff < 0.5 or n < 1:
        raise ValueError(f"Lanczos filter needs 0 < cutoff < 0.5 cycles per sample and n >= 1 (got {cutoff:g}, {n})")
    k = np.arange(-n, n + 1, dtype=np.float64)
    w = 2 * cutoff * np.sinc(2 * cutoff * k) * np.sinc(k / n)  # np.sinc(x) = sin(πx)/(πx)
    return w / w.sum()


def response(weights: np.ndarray, frequency) -> np.ndarray:
    """The filter's response R(f) = Σ w_k cos(2πfk) at ``frequency`` (cycles per sample)."""
    n = (weights.size - 1) // 2
    k = np.arange(-n, n + 1)
    return np.cos(2 * math.pi * np.multiply.outer(np.asarray(frequency, dtype=np.float64), k)) @ weights


@dataclass(frozen=True)
class TimeFilter:
    """Low-pass in time: ``period_days`` the cutoff period, snapshots every
    ``every_hours`` at days target − half_window_days … target + half_window_days
    (default half window: 1.5 periods, 3 days for a 2-day filter)."""

    period_days: float
    every_hours: float = 3.0
    half_window_days: float | None = None

    def __post_init__(self):
        if self.half_window_days is None:
            object.__setattr__(self, "half_window_days", 1.5 * self.period_days)
        for name in ("period_days", "every_hours", "half_window_days"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"filter {name.replace('_', ' ')} must be positive (got {value:g})")
        if 2 * self.every_hours / 24 >= self.period_days:
            raise ValueError(
                f"filter period of {self.period_days:g} days needs snapshots more often than every {self.every_hours:g} h"
            )
        per = self.half_window_days * 24 / self.every_hours
        if abs(per - round(per)) > 1e-9:
            raise ValueError(
                f"filter half window of {self.half_window_days:g} days is not a multiple of its {self.every_hours:g} h snapshots"
            )

    @property
    def n(self) -> int:
        return round(self.half_window_days * 24 / self.every_hours)

    @property
    def weights(self) -> np.ndarray:
        return lanczos_weights(self.every_hours / 24 / self.period_days, self.n)

    def days(self, target: float) -> np.ndarray:
        """The snapshot days around ``target``; ``ValueError`` if the window starts before day 0."""
        if target - self.half_window_days < -1e-9:
            raise ValueError(
                f"filter window of ±{self.half_window_days:g} days around day {target:g} starts before the run"
            )
        return target + self.every_hours / 24 * np.arange(-self.n, self.n + 1)

    def apply(self, snapshots) -> np.ndarray:
        """Σ_k w_k snapshots[k] over the first axis (2n + 1 snapshots, equally spaced)."""
        snapshots = np.asarray(snapshots, dtype=np.float64)
        if snapshots.shape[0] != 2 * self.n + 1:
            raise ValueError(f"the filter needs {2 * self.n + 1} snapshots, got {snapshots.shape[0]}")
        return np.tensordot(self.weights, snapshots, axes=1)
