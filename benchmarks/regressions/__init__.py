"""The regression suite, run by airspeed velocity (asv) on each commit it is asked about
(``benchmarks/asv.conf.json``): the default path's whole process (``whole_run``), and the RHS, a
step, an ensemble step and a gradient on the CPU clock of one thread (``model``).
``SWE_SPHERE_ASV_QUICK=1`` shrinks every grid and run to a few seconds (CI's form: it checks that
the suite runs, not the machine's speed)."""

import os

QUICK = os.environ.get("SWE_SPHERE_ASV_QUICK") == "1"
os.environ.setdefault("SWE_SPHERE_THREADS", "1")  # one thread: the CPU clock repeats on a shared machine
