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
    """Base of the errors below; the message is one line that names the field, value or place.

    Catch it to catch every error swe_sphere raises for a reason it can name; an
    exception of another class is a bug.
    """


class SceneError(SweSphereError, ValueError):
    """An invalid scene or override; the message names the field or value.

    Raised by ``load_scene``, ``Simulation`` and ``swe_sphere.run`` before anything is
    run or written (command line: exit 2).
    """


class ArgumentError(SweSphereError, ValueError):
    """A Python API argument of the wrong type, shape, unit or range; the message names the
    argument, what it takes and what it got.

    Raised by ``gradient``, ``HeightMisfit``, ``PointHeights``, ``HeightObservations``,
    ``CubedSphere`` and the others' arguments that are not a scene's values (those are
    each a ``SceneError``), before anything is run (``core.arguments``).
    """


class OutputError(SweSphereError, ValueError):
    """An output path that must not be written; the message names it.

    The file exists (and ``overwrite`` was not given), it is one of the run's inputs
    (the same name, a link or a hard link), or another process is writing it; raised
    before anything is written (command line: exit 2).
    """


class CheckpointError(SweSphereError, ValueError):
    """A restart file cannot be used; the message says why.

    Unreadable or damaged (checksum, content hash, a state no run makes), of another
    scene, grid or version, or already at the end day asked for (command line: exit 2).
    """


class ResourceError(SweSphereError, RuntimeError):
    """The machine cannot do what was asked; the message says how much memory is needed.

    Raised before the grid's arrays are allocated (command line: exit 3).
    """


class MPIUnavailable(SweSphereError, ValueError):
    """Started by ``mpiexec`` as one of several ranks, but mpi4py cannot be imported
    (an installation to complete: bad input, not an internal error)."""


class StepFailure(SweSphereError, RuntimeError):
    """A step could not be completed; the message says why.

    A solver (the Helmholtz CG, Newton–Krylov, KIOPS) did not converge or met a
    non-finite value (command line: exit 3).
    """


class BlowUp(SweSphereError, RuntimeError):
    """The state became non-finite or the depth non-positive; the message gives step, time and place.

    The run file is closed with every good output time first (command line: exit 3).

    Attributes
    ----------
    result : RunResult
        The run up to the last good step (when raised by ``Simulation.run``).
    """


class Interrupted(SweSphereError, RuntimeError):
    """SIGINT or SIGTERM stopped the run; the message says what is kept.

    The run stops after a complete step (a step still going on
    ``interrupts.ABANDON_AFTER`` s after the signal is abandoned, its state dropped),
    or the signal came after its last step, while its output was being closed (then
    whole). Command line: exit 128 + the signal's number (130, 143).

    Attributes
    ----------
    signum : int
        The signal.
    result : RunResult
        The run up to the last complete step (when raised by ``Simulation.run``).
    checkpoint : Path or None
        The restart file written, if any (likewise).
    """


__all__ = [
    "SweSphereError",
    "SceneError",
    "ArgumentError",
    "OutputError",
    "CheckpointError",
    "ResourceError",
    "MPIUnavailable",
    "StepFailure",
    "BlowUp",
    "Interrupted",
]
