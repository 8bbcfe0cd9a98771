"""The checks of the Python API's arguments: each returns the value in the form the function
uses (a ``Path``, an ``int``, a ``float``, a float array) or raises a ``SweSphereError`` subclass
(``ArgumentError`` unless given another, e.g. ``SceneError``) whose one line names the argument,
what it takes and what it got: never Python's, pathlib's or numpy's own wording from deeper in."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .errors import ArgumentError


def got(value) -> str:
    """A refused value for a message: its repr (shortened), and its type where that is not a number's."""
    text = " ".join(repr(value).split())  # one line: a Dataset's or an array's repr spans several
    text = text if len(text) <= 60 else text[:57] + "..."
    number = isinstance(value, (int, float, np.number)) and not isinstance(value, bool)
    return text if number else f"{text}, a {type(value).__name__}"


def path_argument(name: str, value, takes: str = "a file's path (str or os.PathLike)", error=ArgumentError) -> Path:
    """``value`` as a ``Path``: a non-empty str or ``os.PathLike``."""
    if not isinstance(value, (str, os.PathLike)) or not str(os.fspath(value)).strip():
        raise error(f"{name} must be {takes} (got {got(value)})")
    return Path(value)


def flag_argument(name: str, value, error=ArgumentError) -> bool:
    """``value``, a bool (or numpy's)."""
    if not isinstance(value, (bool, np.bool_)):
        raise error(f"{name} must be True or False (got {got(value)})")
    return bool(value)


def integer_argument(name: str, value, low: int | None = None, error=ArgumentError) -> int:
    """``value`` as an ``int``: an integer (a float of integer value too; not a bool), ≥ ``low``."""
    whole = isinstance(value, (int, np.integer)) or (
        isinstance(value, (float, np.floating)) and math.isfinite(value) and float(value).is_integer()
    )
    if isinstance(value, (bool, np.bool_)) or not whole or (low is not None and value < low):
        raise error(f"{name} must be an integer{'' if low is None else f' >= {low}'} (got {got(value)})")
    return int(value)


def number_argument(
    name: str, value, unit: str = "", low: float | None = None, positive: bool = False, error=ArgumentError
) -> float:
    """``value`` as a finite ``float`` (not a bool), > 0 where ``positive``, ≥ ``low`` where given;
    ``unit`` (e.g. "m") is named in the message."""
    number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    bad = not number or not math.isfinite(value) or (positive and value <= 0) or (low is not None and value < low)
    if bad:
        bound = " > 0" if positive else "" if low is None else f" >= {low:g}"
        raise error(f"{name} must be a finite number{bound}{f' ({unit})' if unit else ''} (got {got(value)})")
    return float(value)


def array_argument(name: str, value, shape: tuple | None = None, unit: str = "", error=ArgumentError) -> np.ndarray:
    """``value`` as a float array of finite numbers, of ``shape`` where given (a scalar is
    refused then; ``None`` in ``shape`` takes any length)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise error(f"{name} must be numbers{f' ({unit})' if unit else ''} (got {got(value)})") from None
    if shape is not None and (a.ndim != len(shape) or any(w is not None and w != n for w, n in zip(shape, a.shape))):
        want = "(" + ", ".join("any" if w is None else str(w) for w in shape) + ("," if len(shape) == 1 else "") + ")"
        raise error(f"{name} must have shape {want} (got {a.shape})")
    if not np.all(np.isfinite(a)):
        raise error(f"{name} must be finite numbers{f' ({unit})' if unit else ''} (got a NaN or an infinity)")
    return a


def mapping_argument(name: str, value, keys: str = "str", error=ArgumentError) -> dict:
    """``value`` as a dict: a mapping whose keys are ``str`` (``keys="str"``) or integers
    (``keys="int"``: returned as ints)."""
    if not isinstance(value, Mapping):
        raise error(f"{name} must be a mapping {{{'key' if keys == 'str' else 'step'}: value}} (got {got(value)})")
    out = {}
    for k, v in value.items():
        if keys == "str" and not isinstance(k, str):
            raise error(f"the keys of {name} must be str (got {got(k)})")
        out[k if keys == "str" else integer_argument(f"the keys of {name}", k, 0, error)] = v
    return out


def callable_argument(name: str, value, takes: str, error=ArgumentError):
    """``value``, a callable."""
    if not callable(value):
        raise error(f"{name} must be {takes} (got {got(value)})")
    return value


def instance_argument(name: str, value, kind: type | tuple, takes: str, error=ArgumentError):
    """``value``, an instance of ``kind`` (a type or a tuple of types)."""
    if not isinstance(value, kind):
        raise error(f"{name} must be {takes} (got {got(value)})")
    return value


def comm_argument(name: str, value, error=ArgumentError):
    """``value``, None or an MPI communicator (what mpi4py's offers: rank, size, bcast, gather)."""
    if value is not None and not all(hasattr(value, verb) for verb in ("rank", "size", "bcast", "gather")):
        raise error(f"{name} must be an mpi4py communicator or None (got {got(value)})")
    return value


__all__ = [
    "comm_argument",
    "got",
    "path_argument",
    "flag_argument",
    "integer_argument",
    "number_argument",
    "array_argument",
    "mapping_argument",
    "callable_argument",
    "instance_argument",
]


def band_argument(name: str, value, top: int | None = None, error=ArgumentError) -> tuple | None:
    """``value`` as a band of spherical-harmonic degrees (l_min, l_max): None, or two integers
    1 ≤ l_min ≤ l_max (≤ ``top`` where given; not bools); ``error`` names ``name``."""
    pair = isinstance(value, tuple | list) and len(value) == 2
    if value is not None and not (
        pair
        and all(isinstance(v, int | np.integer) and not isinstance(v, bool) for v in value)
        and 1 <= value[0] <= value[1] <= (value[1] if top is None else top)
    ):
        shown = list(value) if isinstance(value, tuple | list) else value
        bound = "" if top is None else f" <= {top}"
        raise error(f"{name} must be [l_min, l_max], integers 1 <= l_min <= l_max{bound} (got {shown!r})")
    return None if value is None else (int(value[0]), int(value[1]))
