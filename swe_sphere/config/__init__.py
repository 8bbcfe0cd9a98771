"""The config layer: scenes, from TOML to a validated ``Scene``.

``scene`` (``Scene``, ``load_scene``, ``with_days``, ``resolve_scene``: the names the rest of the
package imports), ``schema`` (the keys and types, the tables' records, the overrides, the file
read), ``resolve`` (a resolver a table: the case, grid, spacing, output, stepper, ...),
``hyperviscosity`` (the ∇⁴'s coefficients, span and every k), ``step_rule`` (``scene_dt``: the
scene's Δt, the one place a scene decides it), ``control`` (step control), ``paths`` (the
bundled scenes, a scene named by path or name, a grid's mesh file). Δt's whole-step rule is
``core.clock``'s ``Clock``, which ``Scene.clock`` gives.

May import: every layer below (``core`` to ``io``).
"""

__all__ = ["paths", "resolve", "schema", "scene"]
