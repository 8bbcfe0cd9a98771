"""The steppers page, generated from the registry (``swe_sphere.STEPPERS``) when the site is
built: each registered stepper's name, its class, its description (the class's docstring: the
scheme, its source, what its options mean) and where its options' table is on the scene keys
page."""

from __future__ import annotations

import importlib
import inspect


def sections() -> list[tuple[str, str, str]]:
    """(label, title, reStructuredText) a registered stepper, in the registry's order."""
    from swe_sphere.config.schema import SCHEMA
    from swe_sphere.steppers import STEPPERS

    out = []
    for name, cls in STEPPERS.items():
        module = importlib.import_module(cls.__module__)
        if getattr(module, cls.__qualname__, None) is cls:
            where = f"``{cls.__module__}.{cls.__qualname__}``"
        else:  # a class the registry makes from a built-in table
            base = cls.__mro__[1]
            where = f"a table of ``{base.__module__}.{base.__qualname__}``"
        options = (
            f"Options: the scene table ``[{name}]`` (:ref:`its keys <scene-{name}>`)."
            if name in SCHEMA
            else "No options of its own."
        )
        out.append((f"stepper-{name}", name, "\n".join([f"Class: {where}.", "", inspect.getdoc(cls), "", options])))
    return out


def setup(app):
    from generated import add  # Sphinx's: only when the site is built

    return add(app, "steppers", sections, "steppers_page.py")
