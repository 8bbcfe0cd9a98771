"""The config layer: scenes, from TOML to a validated ``Scene``.

``scene`` (``Scene``, ``load_scene``, the bundled scenes).

May import: every layer below (``core`` to ``io``).
"""

__all__ = ["scene"]
