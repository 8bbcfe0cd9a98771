"""E3SM's HOMME test meshes beside the checkout (``../shared/meshes``), where present: tests that
read them skip without them; the project's own ``.g`` files (``cube_mesh``) cover the same ground."""

from __future__ import annotations

from pathlib import Path

SHARED = Path(__file__).resolve().parents[2] / "shared" / "meshes"
TEMPEST_NE2 = SHARED / "TEMPEST_NE2.g"  # the uniform ne2 cube, made by TempestRemap
MOUNTAIN = SHARED / "mountain_10_x2.g"  # ne10 refined 2x over TC5's mountain (CUBIT paving)
