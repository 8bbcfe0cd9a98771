"""The scene's Δt and ∇⁴ schedule pinned across the step rule's move into one function (issue
116 item 3): every bundled scene under the command-line choices that reach the rule (``--ne``,
``--np``, ``--dt``, ``-s time.dt``, ``--stepper``, ``hyperviscosity.every`` "auto" or k,
``--precision float32``, ``--restart-every``, a stream, a [filter], a controlled Δt) resolves
to the Δt, its source, the scene file's own Δt (``Scene.own_dt``), the ∇⁴'s k and subcycles,
the filter's weight and the notes on them that ``load_scene`` gave at main 3f0680e, to the bit.

``PINS`` was written by running this module's ``resolved_pins()`` on that commit (``python -c
"import test_step_rule_pins as t, pprint; pprint.pprint(t.resolved_pins())"`` in tests/config);
they are regression pins: a change to them is a change of behaviour, made on purpose. The case-7
scenes (``tc7_*``, issue 115) came after that commit; their lines were added the same way when
they arrived, every other line unchanged, and so were the marker scenes' (``galewsky_marker``,
``tc5_mountain_marker``, issue 125); their float32 lines' refusal was reworded on purpose when it
came to name the precision, not the stepper (``model.precision.tracers_refusal``)."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

from swe_sphere.config.scene import list_scenes, load_scene
from swe_sphere.core.errors import SceneError

# load_scene's keywords, as the command line's flags give them
VARIANTS = {
    "as_is": {},
    "ne4": {"ne": 4},
    "ne6_np6": {"ne": 6, "np_": 6},
    "dt120": {"dt": 120.0},
    "s_dt100_ne8": {"ne": 8, "overrides": {"time.dt": 100.0}},
    "rk4_ne10": {"ne": 10, "stepper": "rk4"},
    "auto": {"overrides": {"hyperviscosity.every": "auto"}},
    "auto_ne8": {"ne": 8, "overrides": {"hyperviscosity.every": "auto"}},
    "auto_ne24_np6": {"ne": 24, "np_": 6, "overrides": {"hyperviscosity.every": "auto"}},
    "every3_ne12": {"ne": 12, "overrides": {"hyperviscosity.every": 3}},
    "float32_auto_ne6": {"ne": 6, "precision": "float32", "overrides": {"hyperviscosity.every": "auto"}},
    "restart_auto_ne5": {"ne": 5, "restart_every": 0.3, "overrides": {"hyperviscosity.every": "auto"}},
    "stream_auto_ne9": {
        "ne": 9,
        "overrides": {
            "hyperviscosity.every": "auto",
            "output.streams": [{"name": "6h", "every_days": 0.25, "fields": ["h"]}],
        },
    },
    "filter_auto_ne8": {"ne": 8, "overrides": {"hyperviscosity.every": "auto", "filter.efold_hours": 2.0}},
    "short_auto_ne3": {"ne": 3, "days": 0.03, "overrides": {"hyperviscosity.every": "auto"}},
    "error_auto_ne8": {
        "ne": 8,
        "stepper": "bs32",
        "overrides": {"time.control": "error", "hyperviscosity.every": "auto"},
    },
}
NOTES = Path(__file__).with_name("step_rule_notes.json")  # the step notes, by key
# the notes that say how Δt, the ∇⁴'s k and the filter's weight were chosen
STEP_NOTES = ("dt ", "warning: dt", "hyperviscosity every", "hyperviscosity.every", "filter mu")


def pin(scene: str, kwargs: dict) -> tuple:
    """(Δt, its source, own Δt, k, subcycles, the filter's mu or None, the step notes) of bundled
    ``scene`` loaded with ``kwargs``, or ("error", the SceneError's line)."""
    try:
        s = load_scene(scene, **kwargs)
    except SceneError as err:
        return ("error", str(err))
    mu = None if s.element_filter is None else s.element_filter[0]
    notes = tuple(n for n in s.notes if n.startswith(STEP_NOTES))
    return (s.dt, s.dt_source, s.own_dt, s.hypervis_every, s.hypervis_subcycle, mu, notes)


def resolved_pins() -> dict:
    """Every bundled scene under every variant: {"scene/variant": ``pin``}."""
    with contextlib.chdir("/"):  # no scene file of the working folder's shadows a bundled name
        return {f"{p.stem}/{v}": pin(p.stem, kw) for p in list_scenes() for v, kw in VARIANTS.items()}


PINS = """
galewsky/as_is 157.66423357664235 157.66423357664235 8 1 - time.dt of scene galewsky
galewsky/ne4 472.1311475409836 472.1311475409836 3 1 - time.dt of scene galewsky scaled to ne=4 np=8
galewsky/ne6_np6 691.2 691.2 2 1 - time.dt of scene galewsky scaled to ne=6 np=6
galewsky/dt120 120.0 157.66423357664235 15 1 - the dt given
galewsky/s_dt100_ne8 150.0 236.0655737704918 12 1 - time.dt of scene galewsky scaled to ne=8 np=8
galewsky/rk4_ne10 187.82608695652175 187.82608695652175 8 1 - time.dt of scene galewsky scaled to ne=10 np=8
galewsky/auto 157.66423357664235 157.66423357664235 8 1 - time.dt of scene galewsky
galewsky/auto_ne8 236.0655737704918 236.0655737704918 6 1 - time.dt of scene galewsky scaled to ne=8 np=8
galewsky/auto_ne24_np6 170.07874015748033 170.07874015748033 8 1 - time.dt of scene galewsky scaled to ne=24 np=6
galewsky/every3_ne12 157.66423357664235 157.66423357664235 3 1 - time.dt of scene galewsky
galewsky/float32_auto_ne6 314.1818181818182 314.1818181818182 5 1 - time.dt of scene galewsky scaled to ne=6 np=8
galewsky/restart_auto_ne5 375.6521739130435 375.6521739130435 4 1 - time.dt of scene galewsky scaled to ne=5 np=8
galewsky/stream_auto_ne9 209.70873786407768 209.70873786407768 8 1 - time.dt of scene galewsky scaled to ne=9 np=8
galewsky/filter_auto_ne8 236.0655737704918 236.0655737704918 6 1 0.17858047838854718 time.dt of scene galewsky scaled to ne=8 np=8
galewsky/short_auto_ne3 518.4 518.4 3 1 - time.dt of scene galewsky scaled to ne=3 np=8
galewsky/error_auto_ne8 236.0655737704918 236.0655737704918 1 1 - time.dt of scene galewsky scaled to ne=8 np=8
galewsky_balanced/as_is 216.0 216.0 1 1 - time.dt of scene galewsky_balanced
galewsky_balanced/ne4 1600.0 1600.0 1 1 - time.dt of scene galewsky_balanced scaled to ne=4 np=4
galewsky_balanced/ne6_np6 457.14285714285717 457.14285714285717 1 1 - time.dt of scene galewsky_balanced scaled to ne=6 np=6
galewsky_balanced/dt120 120.0 216.0 1 1 - the dt given
galewsky_balanced/s_dt100_ne8 374.02597402597405 807.4766355140187 1 1 - time.dt of scene galewsky_balanced scaled to ne=8 np=4
galewsky_balanced/rk4_ne10 644.776119402985 644.776119402985 1 1 - time.dt of scene galewsky_balanced scaled to ne=10 np=4
galewsky_balanced/auto 216.0 216.0 1 1 - time.dt of scene galewsky_balanced
galewsky_balanced/auto_ne8 807.4766355140187 807.4766355140187 1 1 - time.dt of scene galewsky_balanced scaled to ne=8 np=4
galewsky_balanced/auto_ne24_np6 111.34020618556701 111.34020618556701 1 1 - time.dt of scene galewsky_balanced scaled to ne=24 np=6
galewsky_balanced/every3_ne12 540.0 540.0 3 1 - time.dt of scene galewsky_balanced scaled to ne=12 np=4
galewsky_balanced/float32_auto_ne6 1080.0 1080.0 1 1 - time.dt of scene galewsky_balanced scaled to ne=6 np=4
galewsky_balanced/restart_auto_ne5 1234.2857142857142 1234.2857142857142 1 1 - time.dt of scene galewsky_balanced scaled to ne=5 np=4
galewsky_balanced/stream_auto_ne9 720.0 720.0 1 1 - time.dt of scene galewsky_balanced scaled to ne=9 np=4
galewsky_balanced/filter_auto_ne8 807.4766355140187 807.4766355140187 1 1 0.10608942136564671 time.dt of scene galewsky_balanced scaled to ne=8 np=4
galewsky_balanced/short_auto_ne3 1296.0 1296.0 1 1 - time.dt of scene galewsky_balanced scaled to ne=3 np=4
galewsky_balanced/error_auto_ne8 807.4766355140187 807.4766355140187 1 1 - time.dt of scene galewsky_balanced scaled to ne=8 np=4
galewsky_marker/as_is 157.66423357664235 157.66423357664235 8 1 - time.dt of scene galewsky_marker
galewsky_marker/ne4 472.1311475409836 472.1311475409836 3 1 - time.dt of scene galewsky_marker scaled to ne=4 np=8
galewsky_marker/ne6_np6 691.2 691.2 2 1 - time.dt of scene galewsky_marker scaled to ne=6 np=6
galewsky_marker/dt120 120.0 157.66423357664235 15 1 - the dt given
galewsky_marker/s_dt100_ne8 150.0 236.0655737704918 12 1 - time.dt of scene galewsky_marker scaled to ne=8 np=8
galewsky_marker/rk4_ne10 187.82608695652175 187.82608695652175 8 1 - time.dt of scene galewsky_marker scaled to ne=10 np=8
galewsky_marker/auto 157.66423357664235 157.66423357664235 8 1 - time.dt of scene galewsky_marker
galewsky_marker/auto_ne8 236.0655737704918 236.0655737704918 6 1 - time.dt of scene galewsky_marker scaled to ne=8 np=8
galewsky_marker/auto_ne24_np6 170.07874015748033 170.07874015748033 8 1 - time.dt of scene galewsky_marker scaled to ne=24 np=6
galewsky_marker/every3_ne12 157.66423357664235 157.66423357664235 3 1 - time.dt of scene galewsky_marker
galewsky_marker/float32_auto_ne6 error [tracers] with [numerics] precision "float32" does not carry tracers (their tendency and ∇⁴ are float64 alone): use "float64"
galewsky_marker/restart_auto_ne5 375.6521739130435 375.6521739130435 4 1 - time.dt of scene galewsky_marker scaled to ne=5 np=8
galewsky_marker/stream_auto_ne9 209.70873786407768 209.70873786407768 8 1 - time.dt of scene galewsky_marker scaled to ne=9 np=8
galewsky_marker/filter_auto_ne8 236.0655737704918 236.0655737704918 6 1 0.17858047838854718 time.dt of scene galewsky_marker scaled to ne=8 np=8
galewsky_marker/short_auto_ne3 518.4 518.4 3 1 - time.dt of scene galewsky_marker scaled to ne=3 np=8
galewsky_marker/error_auto_ne8 error [tracers] with stepper bs32: its step control weighs u, v and h alone; tracers run with the explicit Runge-Kutta steppers
lauter_unsteady/as_is 150.0 150.0 1 1 - time.dt of scene lauter_unsteady
lauter_unsteady/ne4 600.0 600.0 1 1 - time.dt of scene lauter_unsteady scaled to ne=4 np=4
lauter_unsteady/ne6_np6 169.41176470588235 169.41176470588235 1 1 - time.dt of scene lauter_unsteady scaled to ne=6 np=6
lauter_unsteady/dt120 120.0 150.0 1 1 - the dt given
lauter_unsteady/s_dt100_ne8 200.0 300.0 1 1 - time.dt of scene lauter_unsteady scaled to ne=8 np=4
lauter_unsteady/rk4_ne10 240.0 240.0 1 1 - time.dt of scene lauter_unsteady scaled to ne=10 np=4
lauter_unsteady/auto 150.0 150.0 1 1 - time.dt of scene lauter_unsteady
lauter_unsteady/auto_ne8 300.0 300.0 1 1 - time.dt of scene lauter_unsteady scaled to ne=8 np=4
lauter_unsteady/auto_ne24_np6 42.47787610619469 42.47787610619469 1 1 - time.dt of scene lauter_unsteady scaled to ne=24 np=6
lauter_unsteady/every3_ne12 200.0 200.0 3 1 - time.dt of scene lauter_unsteady scaled to ne=12 np=4
lauter_unsteady/float32_auto_ne6 400.0 400.0 1 1 - time.dt of scene lauter_unsteady scaled to ne=6 np=4
lauter_unsteady/restart_auto_ne5 480.0 480.0 1 1 - time.dt of scene lauter_unsteady scaled to ne=5 np=4
lauter_unsteady/stream_auto_ne9 266.6666666666667 266.6666666666667 1 1 - time.dt of scene lauter_unsteady scaled to ne=9 np=4
lauter_unsteady/filter_auto_ne8 300.0 300.0 1 1 0.040810542890861806 time.dt of scene lauter_unsteady scaled to ne=8 np=4
lauter_unsteady/short_auto_ne3 648.0 648.0 1 1 - time.dt of scene lauter_unsteady scaled to ne=3 np=4
lauter_unsteady/error_auto_ne8 300.0 300.0 1 1 - time.dt of scene lauter_unsteady scaled to ne=8 np=4
tc1_cosine_bell/as_is 900.0 900.0 1 1 - time.dt of scene tc1_cosine_bell
tc1_cosine_bell/ne4 3600.0 3600.0 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=4 np=4
tc1_cosine_bell/ne6_np6 1016.4705882352941 1016.4705882352941 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=6 np=6
tc1_cosine_bell/dt120 120.0 900.0 1 1 - the dt given
tc1_cosine_bell/s_dt100_ne8 200.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=8 np=4
tc1_cosine_bell/rk4_ne10 1440.0 1440.0 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=10 np=4
tc1_cosine_bell/auto 900.0 900.0 1 1 - time.dt of scene tc1_cosine_bell
tc1_cosine_bell/auto_ne8 1800.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=8 np=4
tc1_cosine_bell/auto_ne24_np6 254.86725663716814 254.86725663716814 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=24 np=6
tc1_cosine_bell/every3_ne12 1200.0 1200.0 3 1 - time.dt of scene tc1_cosine_bell scaled to ne=12 np=4
tc1_cosine_bell/float32_auto_ne6 2400.0 2400.0 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=6 np=4
tc1_cosine_bell/restart_auto_ne5 2880.0 2880.0 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=5 np=4
tc1_cosine_bell/stream_auto_ne9 1542.857142857143 1542.857142857143 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=9 np=4
tc1_cosine_bell/filter_auto_ne8 1800.0 1800.0 1 1 0.22119921692859512 time.dt of scene tc1_cosine_bell scaled to ne=8 np=4
tc1_cosine_bell/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=3 np=4
tc1_cosine_bell/error_auto_ne8 1800.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell scaled to ne=8 np=4
tc1_cosine_bell_alpha_0.05/as_is 900.0 900.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05
tc1_cosine_bell_alpha_0.05/ne4 3600.0 3600.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=4 np=4
tc1_cosine_bell_alpha_0.05/ne6_np6 1016.4705882352941 1016.4705882352941 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=6 np=6
tc1_cosine_bell_alpha_0.05/dt120 120.0 900.0 1 1 - the dt given
tc1_cosine_bell_alpha_0.05/s_dt100_ne8 200.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=8 np=4
tc1_cosine_bell_alpha_0.05/rk4_ne10 1440.0 1440.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=10 np=4
tc1_cosine_bell_alpha_0.05/auto 900.0 900.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05
tc1_cosine_bell_alpha_0.05/auto_ne8 1800.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=8 np=4
tc1_cosine_bell_alpha_0.05/auto_ne24_np6 254.86725663716814 254.86725663716814 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=24 np=6
tc1_cosine_bell_alpha_0.05/every3_ne12 1200.0 1200.0 3 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=12 np=4
tc1_cosine_bell_alpha_0.05/float32_auto_ne6 2400.0 2400.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=6 np=4
tc1_cosine_bell_alpha_0.05/restart_auto_ne5 2880.0 2880.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=5 np=4
tc1_cosine_bell_alpha_0.05/stream_auto_ne9 1542.857142857143 1542.857142857143 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=9 np=4
tc1_cosine_bell_alpha_0.05/filter_auto_ne8 1800.0 1800.0 1 1 0.22119921692859512 time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=8 np=4
tc1_cosine_bell_alpha_0.05/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=3 np=4
tc1_cosine_bell_alpha_0.05/error_auto_ne8 1800.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_0.05 scaled to ne=8 np=4
tc1_cosine_bell_alpha_pi2/as_is 900.0 900.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2
tc1_cosine_bell_alpha_pi2/ne4 3600.0 3600.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=4 np=4
tc1_cosine_bell_alpha_pi2/ne6_np6 1016.4705882352941 1016.4705882352941 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=6 np=6
tc1_cosine_bell_alpha_pi2/dt120 120.0 900.0 1 1 - the dt given
tc1_cosine_bell_alpha_pi2/s_dt100_ne8 200.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=8 np=4
tc1_cosine_bell_alpha_pi2/rk4_ne10 1440.0 1440.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=10 np=4
tc1_cosine_bell_alpha_pi2/auto 900.0 900.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2
tc1_cosine_bell_alpha_pi2/auto_ne8 1800.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=8 np=4
tc1_cosine_bell_alpha_pi2/auto_ne24_np6 254.86725663716814 254.86725663716814 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=24 np=6
tc1_cosine_bell_alpha_pi2/every3_ne12 1200.0 1200.0 3 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=12 np=4
tc1_cosine_bell_alpha_pi2/float32_auto_ne6 2400.0 2400.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=6 np=4
tc1_cosine_bell_alpha_pi2/restart_auto_ne5 2880.0 2880.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=5 np=4
tc1_cosine_bell_alpha_pi2/stream_auto_ne9 1542.857142857143 1542.857142857143 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=9 np=4
tc1_cosine_bell_alpha_pi2/filter_auto_ne8 1800.0 1800.0 1 1 0.22119921692859512 time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=8 np=4
tc1_cosine_bell_alpha_pi2/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=3 np=4
tc1_cosine_bell_alpha_pi2/error_auto_ne8 1800.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2 scaled to ne=8 np=4
tc1_cosine_bell_alpha_pi2m0.05/as_is 900.0 900.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05
tc1_cosine_bell_alpha_pi2m0.05/ne4 3600.0 3600.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=4 np=4
tc1_cosine_bell_alpha_pi2m0.05/ne6_np6 1016.4705882352941 1016.4705882352941 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=6 np=6
tc1_cosine_bell_alpha_pi2m0.05/dt120 120.0 900.0 1 1 - the dt given
tc1_cosine_bell_alpha_pi2m0.05/s_dt100_ne8 200.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=8 np=4
tc1_cosine_bell_alpha_pi2m0.05/rk4_ne10 1440.0 1440.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=10 np=4
tc1_cosine_bell_alpha_pi2m0.05/auto 900.0 900.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05
tc1_cosine_bell_alpha_pi2m0.05/auto_ne8 1800.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=8 np=4
tc1_cosine_bell_alpha_pi2m0.05/auto_ne24_np6 254.86725663716814 254.86725663716814 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=24 np=6
tc1_cosine_bell_alpha_pi2m0.05/every3_ne12 1200.0 1200.0 3 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=12 np=4
tc1_cosine_bell_alpha_pi2m0.05/float32_auto_ne6 2400.0 2400.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=6 np=4
tc1_cosine_bell_alpha_pi2m0.05/restart_auto_ne5 2880.0 2880.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=5 np=4
tc1_cosine_bell_alpha_pi2m0.05/stream_auto_ne9 1542.857142857143 1542.857142857143 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=9 np=4
tc1_cosine_bell_alpha_pi2m0.05/filter_auto_ne8 1800.0 1800.0 1 1 0.22119921692859512 time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=8 np=4
tc1_cosine_bell_alpha_pi2m0.05/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=3 np=4
tc1_cosine_bell_alpha_pi2m0.05/error_auto_ne8 1800.0 1800.0 1 1 - time.dt of scene tc1_cosine_bell_alpha_pi2m0.05 scaled to ne=8 np=4
tc2_steady/as_is 300.0 300.0 1 1 - time.dt of scene tc2_steady
tc2_steady/ne4 1200.0 1200.0 1 1 - time.dt of scene tc2_steady scaled to ne=4 np=4
tc2_steady/ne6_np6 338.8235294117647 338.8235294117647 1 1 - time.dt of scene tc2_steady scaled to ne=6 np=6
tc2_steady/dt120 120.0 300.0 1 1 - the dt given
tc2_steady/s_dt100_ne8 200.0 600.0 1 1 - time.dt of scene tc2_steady scaled to ne=8 np=4
tc2_steady/rk4_ne10 480.0 480.0 1 1 - time.dt of scene tc2_steady scaled to ne=10 np=4
tc2_steady/auto 300.0 300.0 1 1 - time.dt of scene tc2_steady
tc2_steady/auto_ne8 600.0 600.0 1 1 - time.dt of scene tc2_steady scaled to ne=8 np=4
tc2_steady/auto_ne24_np6 84.95575221238938 84.95575221238938 1 1 - time.dt of scene tc2_steady scaled to ne=24 np=6
tc2_steady/every3_ne12 400.0 400.0 3 1 - time.dt of scene tc2_steady scaled to ne=12 np=4
tc2_steady/float32_auto_ne6 800.0 800.0 1 1 - time.dt of scene tc2_steady scaled to ne=6 np=4
tc2_steady/restart_auto_ne5 960.0 960.0 1 1 - time.dt of scene tc2_steady scaled to ne=5 np=4
tc2_steady/stream_auto_ne9 526.829268292683 526.829268292683 1 1 - time.dt of scene tc2_steady scaled to ne=9 np=4
tc2_steady/filter_auto_ne8 600.0 600.0 1 1 0.07995558537067675 time.dt of scene tc2_steady scaled to ne=8 np=4
tc2_steady/short_auto_ne3 1296.0 1296.0 1 1 - time.dt of scene tc2_steady scaled to ne=3 np=4
tc2_steady/error_auto_ne8 600.0 600.0 1 1 - time.dt of scene tc2_steady scaled to ne=8 np=4
tc2_steady_alpha_pi4/as_is 300.0 300.0 1 1 - time.dt of scene tc2_steady_alpha_pi4
tc2_steady_alpha_pi4/ne4 1200.0 1200.0 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=4 np=4
tc2_steady_alpha_pi4/ne6_np6 338.8235294117647 338.8235294117647 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=6 np=6
tc2_steady_alpha_pi4/dt120 120.0 300.0 1 1 - the dt given
tc2_steady_alpha_pi4/s_dt100_ne8 200.0 600.0 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=8 np=4
tc2_steady_alpha_pi4/rk4_ne10 480.0 480.0 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=10 np=4
tc2_steady_alpha_pi4/auto 300.0 300.0 1 1 - time.dt of scene tc2_steady_alpha_pi4
tc2_steady_alpha_pi4/auto_ne8 600.0 600.0 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=8 np=4
tc2_steady_alpha_pi4/auto_ne24_np6 84.95575221238938 84.95575221238938 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=24 np=6
tc2_steady_alpha_pi4/every3_ne12 400.0 400.0 3 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=12 np=4
tc2_steady_alpha_pi4/float32_auto_ne6 800.0 800.0 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=6 np=4
tc2_steady_alpha_pi4/restart_auto_ne5 960.0 960.0 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=5 np=4
tc2_steady_alpha_pi4/stream_auto_ne9 526.829268292683 526.829268292683 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=9 np=4
tc2_steady_alpha_pi4/filter_auto_ne8 600.0 600.0 1 1 0.07995558537067675 time.dt of scene tc2_steady_alpha_pi4 scaled to ne=8 np=4
tc2_steady_alpha_pi4/short_auto_ne3 1296.0 1296.0 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=3 np=4
tc2_steady_alpha_pi4/error_auto_ne8 600.0 600.0 1 1 - time.dt of scene tc2_steady_alpha_pi4 scaled to ne=8 np=4
tc3_compact_zonal/as_is 300.0 300.0 1 1 - time.dt of scene tc3_compact_zonal
tc3_compact_zonal/ne4 1200.0 1200.0 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=4 np=4
tc3_compact_zonal/ne6_np6 338.8235294117647 338.8235294117647 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=6 np=6
tc3_compact_zonal/dt120 120.0 300.0 1 1 - the dt given
tc3_compact_zonal/s_dt100_ne8 200.0 600.0 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=8 np=4
tc3_compact_zonal/rk4_ne10 480.0 480.0 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=10 np=4
tc3_compact_zonal/auto 300.0 300.0 1 1 - time.dt of scene tc3_compact_zonal
tc3_compact_zonal/auto_ne8 600.0 600.0 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=8 np=4
tc3_compact_zonal/auto_ne24_np6 84.95575221238938 84.95575221238938 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=24 np=6
tc3_compact_zonal/every3_ne12 400.0 400.0 3 1 - time.dt of scene tc3_compact_zonal scaled to ne=12 np=4
tc3_compact_zonal/float32_auto_ne6 800.0 800.0 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=6 np=4
tc3_compact_zonal/restart_auto_ne5 960.0 960.0 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=5 np=4
tc3_compact_zonal/stream_auto_ne9 526.829268292683 526.829268292683 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=9 np=4
tc3_compact_zonal/filter_auto_ne8 600.0 600.0 1 1 0.07995558537067675 time.dt of scene tc3_compact_zonal scaled to ne=8 np=4
tc3_compact_zonal/short_auto_ne3 1296.0 1296.0 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=3 np=4
tc3_compact_zonal/error_auto_ne8 600.0 600.0 1 1 - time.dt of scene tc3_compact_zonal scaled to ne=8 np=4
tc3_compact_zonal_alpha_pi3/as_is 300.0 300.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3
tc3_compact_zonal_alpha_pi3/ne4 1200.0 1200.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=4 np=4
tc3_compact_zonal_alpha_pi3/ne6_np6 338.8235294117647 338.8235294117647 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=6 np=6
tc3_compact_zonal_alpha_pi3/dt120 120.0 300.0 1 1 - the dt given
tc3_compact_zonal_alpha_pi3/s_dt100_ne8 200.0 600.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=8 np=4
tc3_compact_zonal_alpha_pi3/rk4_ne10 480.0 480.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=10 np=4
tc3_compact_zonal_alpha_pi3/auto 300.0 300.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3
tc3_compact_zonal_alpha_pi3/auto_ne8 600.0 600.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=8 np=4
tc3_compact_zonal_alpha_pi3/auto_ne24_np6 84.95575221238938 84.95575221238938 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=24 np=6
tc3_compact_zonal_alpha_pi3/every3_ne12 400.0 400.0 3 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=12 np=4
tc3_compact_zonal_alpha_pi3/float32_auto_ne6 800.0 800.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=6 np=4
tc3_compact_zonal_alpha_pi3/restart_auto_ne5 960.0 960.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=5 np=4
tc3_compact_zonal_alpha_pi3/stream_auto_ne9 526.829268292683 526.829268292683 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=9 np=4
tc3_compact_zonal_alpha_pi3/filter_auto_ne8 600.0 600.0 1 1 0.07995558537067675 time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=8 np=4
tc3_compact_zonal_alpha_pi3/short_auto_ne3 1296.0 1296.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=3 np=4
tc3_compact_zonal_alpha_pi3/error_auto_ne8 600.0 600.0 1 1 - time.dt of scene tc3_compact_zonal_alpha_pi3 scaled to ne=8 np=4
tc4_forced_low/as_is 240.0 240.0 1 1 - time.dt of scene tc4_forced_low
tc4_forced_low/ne4 960.0 960.0 1 1 - time.dt of scene tc4_forced_low scaled to ne=4 np=4
tc4_forced_low/ne6_np6 271.6981132075472 271.6981132075472 1 1 - time.dt of scene tc4_forced_low scaled to ne=6 np=6
tc4_forced_low/dt120 120.0 240.0 1 1 - the dt given
tc4_forced_low/s_dt100_ne8 200.0 480.0 1 1 - time.dt of scene tc4_forced_low scaled to ne=8 np=4
tc4_forced_low/rk4_ne10 382.3008849557522 382.3008849557522 1 1 - time.dt of scene tc4_forced_low scaled to ne=10 np=4
tc4_forced_low/auto 240.0 240.0 1 1 - time.dt of scene tc4_forced_low
tc4_forced_low/auto_ne8 480.0 480.0 1 1 - time.dt of scene tc4_forced_low scaled to ne=8 np=4
tc4_forced_low/auto_ne24_np6 67.9245283018868 67.9245283018868 1 1 - time.dt of scene tc4_forced_low scaled to ne=24 np=6
tc4_forced_low/every3_ne12 320.0 320.0 3 1 - time.dt of scene tc4_forced_low scaled to ne=12 np=4
tc4_forced_low/float32_auto_ne6 635.2941176470588 635.2941176470588 1 1 - time.dt of scene tc4_forced_low scaled to ne=6 np=4
tc4_forced_low/restart_auto_ne5 720.0 720.0 1 1 - time.dt of scene tc4_forced_low scaled to ne=5 np=4
tc4_forced_low/stream_auto_ne9 423.52941176470586 423.52941176470586 1 1 - time.dt of scene tc4_forced_low scaled to ne=9 np=4
tc4_forced_low/filter_auto_ne8 480.0 480.0 1 1 0.06449301496838226 time.dt of scene tc4_forced_low scaled to ne=8 np=4
tc4_forced_low/short_auto_ne3 864.0 864.0 1 1 - time.dt of scene tc4_forced_low scaled to ne=3 np=4
tc4_forced_low/error_auto_ne8 480.0 480.0 1 1 - time.dt of scene tc4_forced_low scaled to ne=8 np=4
tc5_mountain/as_is 211.76470588235293 211.76470588235293 8 1 - time.dt of scene tc5_mountain
tc5_mountain/ne4 1570.909090909091 1570.909090909091 1 1 - time.dt of scene tc5_mountain scaled to ne=4 np=4
tc5_mountain/ne6_np6 447.6683937823834 447.6683937823834 3 1 - time.dt of scene tc5_mountain scaled to ne=6 np=6
tc5_mountain/dt120 120.0 211.76470588235293 15 1 - the dt given
tc5_mountain/s_dt100_ne8 360.0 785.4545454545455 5 1 - time.dt of scene tc5_mountain scaled to ne=8 np=4
tc5_mountain/rk4_ne10 600.0 600.0 3 1 - time.dt of scene tc5_mountain scaled to ne=10 np=4
tc5_mountain/auto 211.76470588235293 211.76470588235293 8 1 - time.dt of scene tc5_mountain
tc5_mountain/auto_ne8 785.4545454545455 785.4545454545455 2 1 - time.dt of scene tc5_mountain scaled to ne=8 np=4
tc5_mountain/auto_ne24_np6 112.5 112.5 16 1 - time.dt of scene tc5_mountain scaled to ne=24 np=6
tc5_mountain/every3_ne12 526.829268292683 526.829268292683 3 1 - time.dt of scene tc5_mountain scaled to ne=12 np=4
tc5_mountain/float32_auto_ne6 900.0 900.0 2 1 - time.dt of scene tc5_mountain scaled to ne=6 np=4
tc5_mountain/restart_auto_ne5 1234.2857142857142 1234.2857142857142 1 1 - time.dt of scene tc5_mountain scaled to ne=5 np=4
tc5_mountain/stream_auto_ne9 696.7741935483871 696.7741935483871 2 1 - time.dt of scene tc5_mountain scaled to ne=9 np=4
tc5_mountain/filter_auto_ne8 785.4545454545455 785.4545454545455 2 1 0.1960207496686738 time.dt of scene tc5_mountain scaled to ne=8 np=4
tc5_mountain/short_auto_ne3 1296.0 1296.0 1 1 - time.dt of scene tc5_mountain scaled to ne=3 np=4
tc5_mountain/error_auto_ne8 792.6605504587156 792.6605504587156 1 1 - time.dt of scene tc5_mountain scaled to ne=8 np=4
tc5_mountain_homme/as_is 90.0 90.0 1 1 - time.dt of scene tc5_mountain_homme
tc5_mountain_homme/ne4 675.0 675.0 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=4 np=4
tc5_mountain_homme/ne6_np6 191.1504424778761 191.1504424778761 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=6 np=6
tc5_mountain_homme/dt120 120.0 90.0 1 1 - the dt given
tc5_mountain_homme/s_dt100_ne8 374.02597402597405 337.5 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=8 np=4
tc5_mountain_homme/rk4_ne10 270.0 270.0 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=10 np=4
tc5_mountain_homme/auto 90.0 90.0 1 1 - time.dt of scene tc5_mountain_homme
tc5_mountain_homme/auto_ne8 337.5 337.5 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=8 np=4
tc5_mountain_homme/auto_ne24_np6 47.81405644714997 47.81405644714997 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=24 np=6
tc5_mountain_homme/every3_ne12 error hyperviscosity.every = 3: leapfrog_trapezoidal applies its ∇⁴ to a three-level scheme's new level, x(n+1) over 2Δt (1 only; a one-step method takes every > 1)
tc5_mountain_homme/float32_auto_ne6 450.0 450.0 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=6 np=4
tc5_mountain_homme/restart_auto_ne5 540.0 540.0 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=5 np=4
tc5_mountain_homme/stream_auto_ne9 300.0 300.0 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=9 np=4
tc5_mountain_homme/filter_auto_ne8 337.5 337.5 1 1 0.045793334030811685 time.dt of scene tc5_mountain_homme scaled to ne=8 np=4
tc5_mountain_homme/short_auto_ne3 864.0 864.0 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=3 np=4
tc5_mountain_homme/error_auto_ne8 337.5 337.5 1 1 - time.dt of scene tc5_mountain_homme scaled to ne=8 np=4
tc5_mountain_marker/as_is 211.76470588235293 211.76470588235293 8 1 - time.dt of scene tc5_mountain_marker
tc5_mountain_marker/ne4 1570.909090909091 1570.909090909091 1 1 - time.dt of scene tc5_mountain_marker scaled to ne=4 np=4
tc5_mountain_marker/ne6_np6 447.6683937823834 447.6683937823834 3 1 - time.dt of scene tc5_mountain_marker scaled to ne=6 np=6
tc5_mountain_marker/dt120 120.0 211.76470588235293 15 1 - the dt given
tc5_mountain_marker/s_dt100_ne8 360.0 785.4545454545455 5 1 - time.dt of scene tc5_mountain_marker scaled to ne=8 np=4
tc5_mountain_marker/rk4_ne10 600.0 600.0 3 1 - time.dt of scene tc5_mountain_marker scaled to ne=10 np=4
tc5_mountain_marker/auto 211.76470588235293 211.76470588235293 8 1 - time.dt of scene tc5_mountain_marker
tc5_mountain_marker/auto_ne8 785.4545454545455 785.4545454545455 2 1 - time.dt of scene tc5_mountain_marker scaled to ne=8 np=4
tc5_mountain_marker/auto_ne24_np6 112.5 112.5 16 1 - time.dt of scene tc5_mountain_marker scaled to ne=24 np=6
tc5_mountain_marker/every3_ne12 526.829268292683 526.829268292683 3 1 - time.dt of scene tc5_mountain_marker scaled to ne=12 np=4
tc5_mountain_marker/float32_auto_ne6 error [tracers] with [numerics] precision "float32" does not carry tracers (their tendency and ∇⁴ are float64 alone): use "float64"
tc5_mountain_marker/restart_auto_ne5 1234.2857142857142 1234.2857142857142 1 1 - time.dt of scene tc5_mountain_marker scaled to ne=5 np=4
tc5_mountain_marker/stream_auto_ne9 696.7741935483871 696.7741935483871 2 1 - time.dt of scene tc5_mountain_marker scaled to ne=9 np=4
tc5_mountain_marker/filter_auto_ne8 785.4545454545455 785.4545454545455 2 1 0.1960207496686738 time.dt of scene tc5_mountain_marker scaled to ne=8 np=4
tc5_mountain_marker/short_auto_ne3 1296.0 1296.0 1 1 - time.dt of scene tc5_mountain_marker scaled to ne=3 np=4
tc5_mountain_marker/error_auto_ne8 error [tracers] with stepper bs32: its step control weighs u, v and h alone; tracers run with the explicit Runge-Kutta steppers
tc6_rossby_haurwitz/as_is 300.0 300.0 12 1 - time.dt of scene tc6_rossby_haurwitz
tc6_rossby_haurwitz/ne4 1800.0 1800.0 2 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=4 np=4
tc6_rossby_haurwitz/ne6_np6 635.2941176470588 635.2941176470588 4 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=6 np=6
tc6_rossby_haurwitz/dt120 120.0 300.0 30 1 - the dt given
tc6_rossby_haurwitz/s_dt100_ne8 374.02597402597405 1107.6923076923076 7 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=8 np=4
tc6_rossby_haurwitz/rk4_ne10 900.0 900.0 4 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=10 np=4
tc6_rossby_haurwitz/auto 300.0 300.0 12 1 - time.dt of scene tc6_rossby_haurwitz
tc6_rossby_haurwitz/auto_ne8 1107.6923076923076 1107.6923076923076 3 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=8 np=4
tc6_rossby_haurwitz/auto_ne24_np6 159.11602209944752 159.11602209944752 21 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=24 np=6
tc6_rossby_haurwitz/every3_ne12 744.8275862068965 744.8275862068965 3 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=12 np=4
tc6_rossby_haurwitz/float32_auto_ne6 1489.655172413793 1489.655172413793 2 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=6 np=4
tc6_rossby_haurwitz/restart_auto_ne5 1728.0 1728.0 2 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=5 np=4
tc6_rossby_haurwitz/stream_auto_ne9 900.0 900.0 4 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=9 np=4
tc6_rossby_haurwitz/filter_auto_ne8 1107.6923076923076 1107.6923076923076 3 1 0.3696868134032802 time.dt of scene tc6_rossby_haurwitz scaled to ne=8 np=4
tc6_rossby_haurwitz/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=3 np=4
tc6_rossby_haurwitz/error_auto_ne8 1122.077922077922 1122.077922077922 1 1 - time.dt of scene tc6_rossby_haurwitz scaled to ne=8 np=4
tc6_rossby_haurwitz_homme/as_is 90.0 90.0 1 1 - time.dt of scene tc6_rossby_haurwitz_homme
tc6_rossby_haurwitz_homme/ne4 675.0 675.0 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=4 np=4
tc6_rossby_haurwitz_homme/ne6_np6 191.1504424778761 191.1504424778761 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=6 np=6
tc6_rossby_haurwitz_homme/dt120 120.0 90.0 1 1 - the dt given
tc6_rossby_haurwitz_homme/s_dt100_ne8 374.02597402597405 337.5 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=8 np=4
tc6_rossby_haurwitz_homme/rk4_ne10 270.0 270.0 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=10 np=4
tc6_rossby_haurwitz_homme/auto 90.0 90.0 1 1 - time.dt of scene tc6_rossby_haurwitz_homme
tc6_rossby_haurwitz_homme/auto_ne8 337.5 337.5 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=8 np=4
tc6_rossby_haurwitz_homme/auto_ne24_np6 47.81405644714997 47.81405644714997 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=24 np=6
tc6_rossby_haurwitz_homme/every3_ne12 error hyperviscosity.every = 3: leapfrog_trapezoidal applies its ∇⁴ to a three-level scheme's new level, x(n+1) over 2Δt (1 only; a one-step method takes every > 1)
tc6_rossby_haurwitz_homme/float32_auto_ne6 450.0 450.0 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=6 np=4
tc6_rossby_haurwitz_homme/restart_auto_ne5 540.0 540.0 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=5 np=4
tc6_rossby_haurwitz_homme/stream_auto_ne9 300.0 300.0 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=9 np=4
tc6_rossby_haurwitz_homme/filter_auto_ne8 337.5 337.5 1 1 0.045793334030811685 time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=8 np=4
tc6_rossby_haurwitz_homme/short_auto_ne3 864.0 864.0 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=3 np=4
tc6_rossby_haurwitz_homme/error_auto_ne8 337.5 337.5 1 1 - time.dt of scene tc6_rossby_haurwitz_homme scaled to ne=8 np=4
tc6_rossby_haurwitz_inviscid/as_is 90.0 90.0 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid
tc6_rossby_haurwitz_inviscid/ne4 675.0 675.0 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=4 np=4
tc6_rossby_haurwitz_inviscid/ne6_np6 191.1504424778761 191.1504424778761 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=6 np=6
tc6_rossby_haurwitz_inviscid/dt120 120.0 90.0 1 1 - the dt given
tc6_rossby_haurwitz_inviscid/s_dt100_ne8 374.02597402597405 337.5 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=8 np=4
tc6_rossby_haurwitz_inviscid/rk4_ne10 270.0 270.0 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=10 np=4
tc6_rossby_haurwitz_inviscid/auto 90.0 90.0 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid
tc6_rossby_haurwitz_inviscid/auto_ne8 337.5 337.5 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=8 np=4
tc6_rossby_haurwitz_inviscid/auto_ne24_np6 47.81405644714997 47.81405644714997 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=24 np=6
tc6_rossby_haurwitz_inviscid/every3_ne12 error hyperviscosity.every = 3: leapfrog_trapezoidal applies its ∇⁴ to a three-level scheme's new level, x(n+1) over 2Δt (1 only; a one-step method takes every > 1)
tc6_rossby_haurwitz_inviscid/float32_auto_ne6 450.0 450.0 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=6 np=4
tc6_rossby_haurwitz_inviscid/restart_auto_ne5 540.0 540.0 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=5 np=4
tc6_rossby_haurwitz_inviscid/stream_auto_ne9 300.0 300.0 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=9 np=4
tc6_rossby_haurwitz_inviscid/filter_auto_ne8 337.5 337.5 1 1 0.045793334030811685 time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=8 np=4
tc6_rossby_haurwitz_inviscid/short_auto_ne3 864.0 864.0 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=3 np=4
tc6_rossby_haurwitz_inviscid/error_auto_ne8 337.5 337.5 1 1 - time.dt of scene tc6_rossby_haurwitz_inviscid scaled to ne=8 np=4
tc7_era_january/as_is 300.0 300.0 12 1 - time.dt of scene tc7_era_january
tc7_era_january/ne4 1800.0 1800.0 2 1 - time.dt of scene tc7_era_january scaled to ne=4 np=4
tc7_era_january/ne6_np6 583.7837837837837 583.7837837837837 5 1 - time.dt of scene tc7_era_january scaled to ne=6 np=6
tc7_era_january/dt120 120.0 300.0 30 1 - the dt given
tc7_era_january/s_dt100_ne8 374.02597402597405 1122.077922077922 7 1 - time.dt of scene tc7_era_january scaled to ne=8 np=4
tc7_era_january/rk4_ne10 900.0 900.0 4 1 - time.dt of scene tc7_era_january scaled to ne=10 np=4
tc7_era_january/auto 300.0 300.0 12 1 - time.dt of scene tc7_era_january
tc7_era_january/auto_ne8 1122.077922077922 1122.077922077922 3 1 - time.dt of scene tc7_era_january scaled to ne=8 np=4
tc7_era_january/auto_ne24_np6 159.11602209944752 159.11602209944752 15 1 - time.dt of scene tc7_era_january scaled to ne=24 np=6
tc7_era_january/every3_ne12 744.8275862068965 744.8275862068965 3 1 - time.dt of scene tc7_era_january scaled to ne=12 np=4
tc7_era_january/float32_auto_ne6 1489.655172413793 1489.655172413793 2 1 - time.dt of scene tc7_era_january scaled to ne=6 np=4
tc7_era_january/restart_auto_ne5 1728.0 1728.0 2 1 - time.dt of scene tc7_era_january scaled to ne=5 np=4
tc7_era_january/stream_auto_ne9 900.0 900.0 4 1 - time.dt of scene tc7_era_january scaled to ne=9 np=4
tc7_era_january/filter_auto_ne8 1122.077922077922 1122.077922077922 3 1 0.37345361403124266 time.dt of scene tc7_era_january scaled to ne=8 np=4
tc7_era_january/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene tc7_era_january scaled to ne=3 np=4
tc7_era_january/error_auto_ne8 1122.077922077922 1122.077922077922 1 1 - time.dt of scene tc7_era_january scaled to ne=8 np=4
tc7_era_july/as_is 300.0 300.0 12 1 - time.dt of scene tc7_era_july
tc7_era_july/ne4 1800.0 1800.0 2 1 - time.dt of scene tc7_era_july scaled to ne=4 np=4
tc7_era_july/ne6_np6 583.7837837837837 583.7837837837837 5 1 - time.dt of scene tc7_era_july scaled to ne=6 np=6
tc7_era_july/dt120 120.0 300.0 30 1 - the dt given
tc7_era_july/s_dt100_ne8 374.02597402597405 1122.077922077922 7 1 - time.dt of scene tc7_era_july scaled to ne=8 np=4
tc7_era_july/rk4_ne10 900.0 900.0 4 1 - time.dt of scene tc7_era_july scaled to ne=10 np=4
tc7_era_july/auto 300.0 300.0 12 1 - time.dt of scene tc7_era_july
tc7_era_july/auto_ne8 1122.077922077922 1122.077922077922 3 1 - time.dt of scene tc7_era_july scaled to ne=8 np=4
tc7_era_july/auto_ne24_np6 159.11602209944752 159.11602209944752 15 1 - time.dt of scene tc7_era_july scaled to ne=24 np=6
tc7_era_july/every3_ne12 744.8275862068965 744.8275862068965 3 1 - time.dt of scene tc7_era_july scaled to ne=12 np=4
tc7_era_july/float32_auto_ne6 1489.655172413793 1489.655172413793 2 1 - time.dt of scene tc7_era_july scaled to ne=6 np=4
tc7_era_july/restart_auto_ne5 1728.0 1728.0 2 1 - time.dt of scene tc7_era_july scaled to ne=5 np=4
tc7_era_july/stream_auto_ne9 900.0 900.0 4 1 - time.dt of scene tc7_era_july scaled to ne=9 np=4
tc7_era_july/filter_auto_ne8 1122.077922077922 1122.077922077922 3 1 0.37345361403124266 time.dt of scene tc7_era_july scaled to ne=8 np=4
tc7_era_july/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene tc7_era_july scaled to ne=3 np=4
tc7_era_july/error_auto_ne8 1122.077922077922 1122.077922077922 1 1 - time.dt of scene tc7_era_july scaled to ne=8 np=4
tc7_ncep_june/as_is 300.0 300.0 12 1 - time.dt of scene tc7_ncep_june
tc7_ncep_june/ne4 1800.0 1800.0 2 1 - time.dt of scene tc7_ncep_june scaled to ne=4 np=4
tc7_ncep_june/ne6_np6 583.7837837837837 583.7837837837837 5 1 - time.dt of scene tc7_ncep_june scaled to ne=6 np=6
tc7_ncep_june/dt120 120.0 300.0 30 1 - the dt given
tc7_ncep_june/s_dt100_ne8 374.02597402597405 1122.077922077922 7 1 - time.dt of scene tc7_ncep_june scaled to ne=8 np=4
tc7_ncep_june/rk4_ne10 900.0 900.0 4 1 - time.dt of scene tc7_ncep_june scaled to ne=10 np=4
tc7_ncep_june/auto 300.0 300.0 12 1 - time.dt of scene tc7_ncep_june
tc7_ncep_june/auto_ne8 1122.077922077922 1122.077922077922 3 1 - time.dt of scene tc7_ncep_june scaled to ne=8 np=4
tc7_ncep_june/auto_ne24_np6 159.11602209944752 159.11602209944752 15 1 - time.dt of scene tc7_ncep_june scaled to ne=24 np=6
tc7_ncep_june/every3_ne12 744.8275862068965 744.8275862068965 3 1 - time.dt of scene tc7_ncep_june scaled to ne=12 np=4
tc7_ncep_june/float32_auto_ne6 1489.655172413793 1489.655172413793 2 1 - time.dt of scene tc7_ncep_june scaled to ne=6 np=4
tc7_ncep_june/restart_auto_ne5 1728.0 1728.0 2 1 - time.dt of scene tc7_ncep_june scaled to ne=5 np=4
tc7_ncep_june/stream_auto_ne9 900.0 900.0 4 1 - time.dt of scene tc7_ncep_june scaled to ne=9 np=4
tc7_ncep_june/filter_auto_ne8 1122.077922077922 1122.077922077922 3 1 0.37345361403124266 time.dt of scene tc7_ncep_june scaled to ne=8 np=4
tc7_ncep_june/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene tc7_ncep_june scaled to ne=3 np=4
tc7_ncep_june/error_auto_ne8 1122.077922077922 1122.077922077922 1 1 - time.dt of scene tc7_ncep_june scaled to ne=8 np=4
ark2_gkc/as_is 1800.0 1800.0 1 1 - time.dt of scene ark2_gkc
ark2_gkc/ne4 7200.0 7200.0 1 1 - time.dt of scene ark2_gkc scaled to ne=4 np=4
ark2_gkc/ne6_np6 2009.3023255813953 2009.3023255813953 1 1 - time.dt of scene ark2_gkc scaled to ne=6 np=6
ark2_gkc/dt120 120.0 1800.0 1 1 - the dt given
ark2_gkc/s_dt100_ne8 200.0 3600.0 1 1 - time.dt of scene ark2_gkc scaled to ne=8 np=4
ark2_gkc/rk4_ne10 2880.0 2880.0 1 1 - time.dt of scene ark2_gkc scaled to ne=10 np=4
ark2_gkc/auto 1800.0 1800.0 1 1 - time.dt of scene ark2_gkc
ark2_gkc/auto_ne8 3600.0 3600.0 1 1 - time.dt of scene ark2_gkc scaled to ne=8 np=4
ark2_gkc/auto_ne24_np6 485.39325842696627 485.39325842696627 3 1 - time.dt of scene ark2_gkc scaled to ne=24 np=6
ark2_gkc/every3_ne12 2400.0 2400.0 3 1 - time.dt of scene ark2_gkc scaled to ne=12 np=4
ark2_gkc/float32_auto_ne6 4800.0 4800.0 1 1 - time.dt of scene ark2_gkc scaled to ne=6 np=4
ark2_gkc/restart_auto_ne5 4320.0 4320.0 1 1 - time.dt of scene ark2_gkc scaled to ne=5 np=4
ark2_gkc/stream_auto_ne9 3085.714285714286 3085.714285714286 1 1 - time.dt of scene ark2_gkc scaled to ne=9 np=4
ark2_gkc/filter_auto_ne8 3600.0 3600.0 1 1 0.3934693402873666 time.dt of scene ark2_gkc scaled to ne=8 np=4
ark2_gkc/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene ark2_gkc scaled to ne=3 np=4
ark2_gkc/error_auto_ne8 3600.0 3600.0 1 1 - time.dt of scene ark2_gkc scaled to ne=8 np=4
ark324l2sa/as_is 1800.0 1800.0 1 1 - time.dt of scene ark324l2sa
ark324l2sa/ne4 7200.0 7200.0 1 1 - time.dt of scene ark324l2sa scaled to ne=4 np=4
ark324l2sa/ne6_np6 2009.3023255813953 2009.3023255813953 1 1 - time.dt of scene ark324l2sa scaled to ne=6 np=6
ark324l2sa/dt120 120.0 1800.0 1 1 - the dt given
ark324l2sa/s_dt100_ne8 200.0 3600.0 1 1 - time.dt of scene ark324l2sa scaled to ne=8 np=4
ark324l2sa/rk4_ne10 2880.0 2880.0 1 1 - time.dt of scene ark324l2sa scaled to ne=10 np=4
ark324l2sa/auto 1800.0 1800.0 1 1 - time.dt of scene ark324l2sa
ark324l2sa/auto_ne8 3600.0 3600.0 1 1 - time.dt of scene ark324l2sa scaled to ne=8 np=4
ark324l2sa/auto_ne24_np6 485.39325842696627 485.39325842696627 3 1 - time.dt of scene ark324l2sa scaled to ne=24 np=6
ark324l2sa/every3_ne12 2400.0 2400.0 3 1 - time.dt of scene ark324l2sa scaled to ne=12 np=4
ark324l2sa/float32_auto_ne6 4800.0 4800.0 1 1 - time.dt of scene ark324l2sa scaled to ne=6 np=4
ark324l2sa/restart_auto_ne5 4320.0 4320.0 1 1 - time.dt of scene ark324l2sa scaled to ne=5 np=4
ark324l2sa/stream_auto_ne9 3085.714285714286 3085.714285714286 1 1 - time.dt of scene ark324l2sa scaled to ne=9 np=4
ark324l2sa/filter_auto_ne8 3600.0 3600.0 1 1 0.3934693402873666 time.dt of scene ark324l2sa scaled to ne=8 np=4
ark324l2sa/short_auto_ne3 2592.0 2592.0 1 1 - time.dt of scene ark324l2sa scaled to ne=3 np=4
ark324l2sa/error_auto_ne8 3600.0 3600.0 1 1 - time.dt of scene ark324l2sa scaled to ne=8 np=4
"""


def as_line(key: str, value: tuple) -> str:
    """A ``PINS`` line: the key, Δt, own Δt, k, subcycles, mu ("-": none) and the source; or the
    key, "error" and the line."""
    if value[0] == "error":
        return f"{key} error {value[1]}"
    dt, source, own, k, subcycle, mu, _ = value
    return " ".join([key, *("-" if v is None else repr(v) for v in (dt, own, k, subcycle, mu)), source])


def test_every_scene_resolves_the_pinned_dt_and_hyperviscosity_schedule():
    """Each scene and variant as pinned, Δt to the bit (the shortest repr reads back exactly),
    and the step notes as ``step_rule_notes.json`` holds them."""
    got = resolved_pins()
    lines = [as_line(key, value) for key, value in got.items()]
    want = PINS.strip().splitlines()
    assert len(lines) == len(want) == 24 * len(VARIANTS)
    differ = [(a, b) for a, b in zip(lines, want) if a != b]
    assert not differ, f"{len(differ)} differ, first: {differ[0][0]!r} != {differ[0][1]!r}"
    notes = json.loads(NOTES.read_text())
    assert {key: list(v[6]) for key, v in got.items() if v[0] != "error" and v[6]} == notes
    # leapfrog_trapezoidal's every = 3; the marker scenes' float32 and step control (tracers refused)
    assert sum(v[0] == "error" for v in got.values()) == 3 + 4
