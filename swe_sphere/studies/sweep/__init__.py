"""Step-size efficiency sweeps: error against Δt against cost, per stepper, and which stepper
reaches an accuracy cheapest. ``plan`` checks the options of `swe-sphere sweep` and ``Plan.run``
runs them (``plan``); ``Sweep`` makes the runs (``runs``), each kept with its key and reused
where made with the same settings (``store``); the verdicts judge them against "sufficient
accuracy", temporal error ≤ 10 % of the spatial error (Evans, Taylor & Drake 2010;
``verdicts``); the summary and files are ``report``'s; a sweep over an ensemble's perturbed
starts, each run's errors with their spread, ``members``'."""

from .members import Members
from .plan import Plan, ResolvedPlan, plan
from .report import OUTPUTS
from .runs import Sweep, explicit_limits, start_state
from .verdicts import CRITERIA

__all__ = ["CRITERIA", "Members", "OUTPUTS", "Plan", "ResolvedPlan", "Sweep", "explicit_limits", "plan", "start_state"]
