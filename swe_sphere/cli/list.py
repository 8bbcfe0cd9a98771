"""``swe-sphere list``: the bundled scenes, the steppers and the terms."""

from __future__ import annotations

import re


def command(args) -> int:
    from ..config.scene import list_scenes, load_scene
    from ..model.arguments import TERMS
    from ..steppers import STEPPERS

    print("scenes:")
    for path in list_scenes():
        s = load_scene(path)
        print(f"  {path.stem:32s} {s.description}")
        stepper = STEPPERS[s.stepper].label(s.stepper_options)
        print(f"  {'':32s} ne={s.ne} np={s.np} {stepper} dt={s.dt:g}s {s.days:g} days; terms: {', '.join(s.terms)}")
    print("steppers:")
    for name, cls in STEPPERS.items():
        summary = " ".join(cls.__doc__.split("\n\n")[0].split())  # the first paragraph, unwrapped
        summary = summary.replace("``", "")  # reST literals read as plain text on a terminal
        sentence = _first_sentence(summary)
        print(f"  {name:32s} {sentence}.")
        print(f"  {'':32s} {_traits(cls)}.")
    print("terms:")
    print("  " + ", ".join(TERMS))
    return 0


def _traits(cls) -> str:
    """What a stepper class offers, in a few words: explicit (a Courant limit), a gradient
    (``swe_sphere.gradient``: ``Stepper.differentiable``), error control (an embedded pair's
    order) and Δt changed between steps (``variable_dt``: a controlled run's)."""
    if cls.name == "tableau":
        return "explicit or IMEX by its table; a gradient; error control where the table has an embedding"
    words = ["explicit"] if cls.explicit else []  # the others' kind their sentence says
    words.append("a gradient" if cls.differentiable else "no gradient")
    order = cls.embedded_order
    if order:
        words.append(f"error control (an embedded order-{order} estimate)")
    elif not cls.variable_dt:
        words.append("one Δt a run")
    return "; ".join(words)


def _first_sentence(text: str) -> str:
    """The first sentence of ``text``, without its full stop: up to a ". " before a capital outside
    parentheses ("eq. 2" and a citation's "(… 1989, Appl. Numer. Math.)" kept whole)."""
    for match in re.finditer(r"\.\s+(?=[A-Z])", text):
        if text.count("(", 0, match.start()) == text.count(")", 0, match.start()):
            return text[: match.start()]
    return text.rstrip(".")
