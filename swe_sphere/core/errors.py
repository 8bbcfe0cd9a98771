"""The errors swe_sphere raises on purpose, under one base.

``SweSphereError`` is the base of every error the model raises for a reason it
can name (bad input, a step that cannot be completed, a run that blew up or was
stopped); each keeps the built-in base it had (``ValueError`` for bad input,
``RuntimeError`` for a run that cannot go on), so ``except ValueError`` still
catches bad input. The command line prints each as one line (exit 2 for bad
input, 3 for a blow-up or a failed step, 130/143 for a stop); anything else is an
internal error.
"""

from __future__ import annotations


class SweSphereError(Exception):
    """Base of the errors below; the message is one line that names the field, value or place."""


class SceneError(SweSphereError, ValueError):
    """Invalid scene or override; the message names the field or value."""


class OutputError(SweSphereError, ValueError):
    """An output path that must not be written; the message names it."""


class CheckpointError(SweSphereError, ValueError):
    """A checkpoint cannot be used; the message says why."""


class ResourceError(SweSphereError, RuntimeError):
    """The machine cannot do what was asked (too little memory); the message says how much is needed."""


class MPIUnavailable(SweSphereError, ValueError):
    """Started by ``mpiexec`` as one of several ranks, but mpi4py cannot be imported
    (an installation to complete: bad input, not an internal error)."""


class StepFailure(SweSphereError, RuntimeError):
    """A step could not be completed (a solver did not converge); the message says why."""


class BlowUp(SweSphereError, RuntimeError):
    """The state became non-finite or the depth non-positive; the message gives step, time and place."""


class Interrupted(SweSphereError, RuntimeError):
    """SIGINT or SIGTERM stopped the run after a complete step (a step still going
    on ``interrupts.ABANDON_AFTER`` s after the signal is abandoned, its state dropped), or
    came after its last step, while its output was being closed (then whole);
    ``signum``, ``result`` and ``checkpoint`` (the restart file written, or None)
    are attached."""


__all__ = [
    "SweSphereError",
    "SceneError",
    "OutputError",
    "CheckpointError",
    "ResourceError",
    "MPIUnavailable",
    "StepFailure",
    "BlowUp",
    "Interrupted",
]
