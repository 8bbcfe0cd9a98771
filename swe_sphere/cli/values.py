"""The values of flags that argparse cannot check alone: ``-s`` overrides (and
``--precision``'s), stepper lists, comma-separated numbers, ``--runs`` pairs, ``--vary`` values and a perturbation's degrees."""

from __future__ import annotations

import math
from pathlib import Path


def overrides(pairs) -> dict:
    """``-s section.key=value`` pairs → {"section.key": value} (TOML values; a bare word is a string)."""
    import tomllib

    out = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"-s needs SECTION.KEY=VALUE (got {pair!r})")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        out[key] = value
    return out


def scene_overrides(args) -> dict:
    """A command's ``-s`` overrides (``overrides``) with ``--precision P`` as ``numerics.precision``;
    ValueError for a ``-s numerics.precision`` that --precision contradicts."""
    out = overrides(args.set)
    if args.precision is not None:
        given = out.setdefault("numerics.precision", args.precision)
        if given != args.precision:
            raise ValueError(f"--precision {args.precision} and -s numerics.precision={given}: give one of them")
    return out


def restart_precision(precision: str | None, scene, path: Path) -> None:
    """Refuse (``CheckpointError``, one line) a ``--precision`` other than that of the scene of the
    restart file ``path`` (``run --continue``, ``sweep --from``): its runs go on in their own."""
    from ..core.errors import CheckpointError

    if precision is not None and precision != scene.precision:
        raise CheckpointError(f"{path} is a run in {scene.precision} and continues in it: no --precision {precision}")


def numbers(text: str, name: str) -> list[float]:
    """``--name 1,2.5`` → [1.0, 2.5]; the sweep's plan checks the values."""
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--{name} must be comma-separated numbers (got {text!r})") from None


def integers(text: str, name: str) -> list[int]:
    """``--name 8,16`` → [8, 16]; the frontier's plan checks the values."""
    try:
        return [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--{name} must be comma-separated integers (got {text!r})") from None


def steppers(text: str) -> list[str]:
    """``--steppers a,b`` → ["a", "b"], each a registered stepper."""
    from ..steppers import STEPPERS

    names = [s for s in text.split(",") if s]
    if not names:
        raise ValueError(f"--steppers names no stepper (got {text!r})")
    for s in names:
        if s not in STEPPERS:
            raise ValueError(f"unknown stepper {s!r} (known: {', '.join(STEPPERS)})")
    return names


def runs(text: str) -> list[tuple[str, float | str]]:
    """``--runs rk4@1,imex@5,bs32@rtol=1e-5`` → [("rk4", 1.0), ("imex", 5.0), ("bs32", "rtol=1e-5")]:
    a multiple of the gravity-wave limit, or a controlled run's KEY=VALUE (the sweep's plan checks it)."""
    pairs = []
    for item in text.split(","):
        name, sep, factor = item.strip().partition("@")
        if not sep or not name.strip():
            raise ValueError(f"--runs needs STEPPER@COURANT or STEPPER@KEY=VALUE (got {item.strip()!r})")
        stepper = steppers(name.strip())[0]
        if "=" in factor:
            pairs.append((stepper, factor.strip()))
            continue
        try:
            multiple = float(factor)
        except ValueError:
            multiple = math.nan
        if not (math.isfinite(multiple) and multiple > 0):  # the multiple of the gravity-wave limit
            raise ValueError(
                f"--runs {item.strip()}: {factor.strip()!r} is not a number > 0 (a multiple of the gravity-wave "
                f"limit, e.g. {stepper}@0.5)"
            )
        pairs.append((stepper, multiple))
    return pairs


def named_output(path: Path | None, kind: str, suffixes: tuple[str, ...]) -> Path | None:
    """``--output`` of a command that writes ``kind`` files: refused unless its name ends in one
    of ``suffixes`` (a file under another name is found by nothing that looks for one, or is
    taken for another format)."""
    if path is not None and path.suffix not in suffixes:
        raise ValueError(f"--output {path}: the file is {kind}, its name must end in {' or '.join(suffixes)}")
    return path


def netcdf_output(path: Path | None) -> Path | None:
    """``--output`` of a command that writes netCDF (a run file): it ends in .nc."""
    return named_output(path, "netCDF", (".nc",))


def exodus_output(path: Path | None) -> Path | None:
    """``--output`` of ``mesh``: an Exodus II mesh, named .g (HOMME's) or .exo, not a run file's .nc."""
    return named_output(path, "an Exodus II mesh", (".g", ".exo"))


def varied(items) -> dict:
    """``--vary`` KEY=V1,V2,... items → {key: [floats]} (one value a member); ValueError naming
    an item that is not one, or a key given twice (the last would replace the first unseen)."""
    out, given = {}, {}
    for item in items:
        key, _, values = item.partition("=")
        key = key.strip()
        try:
            numbers = [float(v) for v in values.split(",")]
        except ValueError:
            raise ValueError(f"--vary {item!r}: give KEY=V1,V2,... (numbers, one a member)") from None
        if not key or not values:
            raise ValueError(f"--vary {item!r}: give KEY=V1,V2,... (numbers, one a member)")
        if key in out:
            raise ValueError(f"--vary {given[key]!r} and {item!r}: {key} is varied twice; give each key once")
        out[key], given[key] = numbers, item
    return out


def degree_band(text: str, scene=None) -> tuple[int, int]:
    """``--perturbation-degrees 1,20`` → (1, 20); ValueError for anything but two integers
    1 <= L_MIN <= L_MAX, or an L_MAX past the degrees the grid of ``scene`` (a ``Scene``) resolves
    (``members.initial.check_band``)."""
    from ..members.initial import check_band

    parts = text.split(",")
    try:
        low, high = (int(p) for p in parts)
    except ValueError:
        raise ValueError(f"--perturbation-degrees {text!r}: give L_MIN,L_MAX (two integers)") from None
    if not 1 <= low <= high:
        raise ValueError(f"--perturbation-degrees {text}: give L_MIN,L_MAX with 1 <= L_MIN <= L_MAX")
    if scene is not None:
        check_band((low, high), scene, "--perturbation-degrees")
    return low, high
