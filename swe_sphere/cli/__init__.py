"""Command line: ``swe-sphere run | list | plot | remap | sweep | stability | mesh``.

Exit status: 0 success; 2 bad input (one line naming the field or value, no
output file); 3 blow-up, solver failure or too little memory (message with
step, model time and place; the output file keeps every good output time);
130 / 143 interrupted by SIGINT / SIGTERM (output so far and a restart file
kept; also for a signal once the outputs are complete); 1 an internal error. Every failure is one line on stderr; ``--debug``
(or SWE_SPHERE_DEBUG=1) shows the traceback instead.

Rooms: ``main`` (the entry point, error classification), ``exits`` (exit statuses,
signals, the process's end), ``parser`` (the flags: one parent parser for the scene
flags, one function a subcommand), ``values`` (flag values the parser cannot check
alone), and one module a command.
"""

from .main import main
from .parser import PLOT_FIELDS, STABILITY_CASES

__all__ = ["PLOT_FIELDS", "STABILITY_CASES", "main"]
