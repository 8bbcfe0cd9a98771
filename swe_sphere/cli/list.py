"""``swe-sphere list``: the bundled scenes, the steppers and the terms."""

from __future__ import annotations


def command(args) -> int:
    import re

    from ..config.scene import list_scenes, load_scene
    from ..model.shallow_water import TERMS
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
        sentence = re.split(r"\.\s+(?=[A-Z])", summary)[0].rstrip(".")  # the first sentence, whole ("eq. 2" kept)
        print(f"  {name:32s} {sentence}.")
    print("terms:")
    print("  " + ", ".join(TERMS))
    return 0
