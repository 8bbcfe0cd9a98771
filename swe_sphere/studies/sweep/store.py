"""The sweep's run cache: each run, the small-Δt reference run and a digital-filter start is
kept under ``DIR/runs/`` with its key, everything that makes it (the resolved scene but its
``PROSE``, what it is scored against, the time filter, the device and ``code_version``), and
reused only where the stored key is the one a rerun would make; ``stale`` says in a few words
what changed otherwise."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import json
from pathlib import Path

import numpy as np

from ...config.scene import Scene
from ...core.runtime import package_version
from ...io.output_files import atomic_path


@functools.cache
def code_version() -> dict:
    """This installation's ``version`` and ``source_sha256``: the SHA-256 (16 hex
    digits) of the ``swe_sphere`` and ``swe_sphere.kernels`` packages' Python
    source, subpackages (``steppers``) included. A sweep reuses a run only when both
    are those it was made with: which edits change no number, only a person can tell."""
    digest = hashlib.sha256()
    for package in ("swe_sphere", "swe_sphere.kernels"):
        root = Path(importlib.util.find_spec(package).origin).parent
        for path in sorted(root.rglob("*.py")):  # subpackages too: the steppers
            digest.update(f"{package}/{path.relative_to(root).as_posix()}\0".encode())
            digest.update(path.read_bytes())
    return {"version": package_version(), "source_sha256": digest.hexdigest()[:16]}


def canonical(value) -> str:
    """``value`` as JSON with sorted keys (tuples as lists): keys compare as these strings."""
    return json.dumps(value, sort_keys=True, default=str)


def changes(old, new, prefix: str = "") -> list[str]:
    """Where the key ``old`` (as stored) differs from ``new``, one item per setting,
    e.g. "scene.days 2.0 (now 1.0)"."""
    if isinstance(old, dict) and isinstance(new, dict):
        return [c for k in sorted(set(old) | set(new)) for c in changes(old.get(k), new.get(k), f"{prefix}{k}.")]
    return [] if canonical(old) == canonical(new) else [f"{prefix.rstrip('.')} {canonical(old)} (now {canonical(new)})"]


def stale(stored: dict | None, key: dict) -> str | None:
    """Why a file whose key is ``stored`` (None: a file without one) cannot stand
    for one made with ``key``, in a few words; None when it can."""
    if stored is None:
        return "made by an earlier swe_sphere that did not record its settings"
    diff = changes(stored, key)
    if not diff:
        return None
    return "other settings: " + ", ".join(diff[:3]) + (f" and {len(diff) - 3} more" if len(diff) > 3 else "")


def read_npz(path: Path, key: dict) -> tuple[dict | None, str | None]:
    """(arrays, None) of the .npz ``path`` made with ``key``; (None, why not) for a
    file made otherwise; (None, None) when there is none."""
    if not path.exists():
        return None, None
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    why = stale(json.loads(str(arrays.pop("key"))) if "key" in arrays else None, key)
    return (None, why) if why else (arrays, None)


def file_sha256(path: Path) -> str:
    """The SHA-256 (hex) of the file at ``path``."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def write_npz(path: Path, key: dict, **arrays) -> None:
    """Write ``arrays`` and ``key`` (as ``canonical`` JSON) to the .npz ``path``, atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as out:
            np.savez(out, key=np.array(canonical(key)), **arrays)


PROSE = (
    "description",
    "notes",
    "log_every_steps",
)  # scene values that describe or report a run, not make it: in no key
# Scene values a digital-filter start does not depend on either (``initialization.digital_filter``
# leaves ∇⁴ out and takes its own steps): a sweep with another of them shares the start
NOT_IN_START = (
    *PROSE,
    "name",
    "days",
    "dt",
    "stepper",
    "stepper_options",
    "output_every_days",
    "reference",
    "nu",
    "nu_div",
    "nu_s",
    "hypervis_subcycle",
)


def run_key(scene: Scene, *, truth: dict, device: str, code: dict, time_filter=None, **more) -> dict:
    """What makes a run of ``scene`` (as stored in its file): the resolved scene (case,
    grid, days, Δt, stepper and its options, the overrides applied, the reference's
    path; not its ``PROSE``), what it is scored against (``truth``: the reference file's
    name and SHA-256), the time filter (``timefilter.TimeFilter`` or None), the device,
    ``code`` (``code_version``) and ``more`` (a swept run: the small-Δt run's Δt, which
    its temporal errors are against); as read back from JSON (tuples as lists)."""
    return json.loads(
        canonical(
            {
                "scene": {k: v for k, v in scene.as_dict().items() if k not in PROSE},
                "truth": truth,
                "device": device,
                "code": code,
                "time_filter": None if time_filter is None else dataclasses.asdict(time_filter),
                **more,
            }
        )
    )


def start_key(scene: Scene, device: str) -> dict:
    """What makes a digital-filter start of ``scene`` on ``device``: the scene but
    ``NOT_IN_START``, the device and ``code_version``; as read back from JSON."""
    return json.loads(
        canonical(
            {
                "scene": {k: v for k, v in scene.as_dict().items() if k not in NOT_IN_START},
                "device": device,
                "code": code_version(),
            }
        )
    )
