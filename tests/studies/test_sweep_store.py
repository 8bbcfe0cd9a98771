"""The sweep's run cache: what a key covers and what a stale one says changed."""

import json
from pathlib import Path

from swe_sphere.studies.sweep import store


def test_the_code_version_covers_the_steppers_subpackage(monkeypatch):
    """A stepper's source is in ``code_version``'s hash, so a sweep does not reuse runs made
    before an edit of it (swe_sphere/steppers/*.py, a subpackage)."""
    before = store.code_version.__wrapped__()["source_sha256"]
    real = Path.read_bytes
    monkeypatch.setattr(Path, "read_bytes", lambda p: real(p) + (b"#" if p.name == "multirate.py" else b""))
    assert store.code_version.__wrapped__()["source_sha256"] != before


def test_a_stored_key_says_what_changed():
    key = {"scene": {"days": 1.0, "ne": 2, "stepper_options": {}}, "device": "cpu"}
    assert store.stale(key, json.loads(json.dumps(key))) is None
    assert store.stale({**key, "scene": {**key["scene"], "days": 2.0, "ne": 4}}, key) == (
        "other settings: scene.days 2.0 (now 1.0), scene.ne 4 (now 2)"
    )
    assert store.stale({**key, "device": "cuda", "code": {"version": "0.0.1"}}, key) == (
        'other settings: code {"version": "0.0.1"} (now null), device "cuda" (now "cpu")'
    )
    assert store.stale(None, key) == "made by an earlier swe_sphere that did not record its settings"
