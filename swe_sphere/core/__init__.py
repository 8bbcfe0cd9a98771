"""The layer above the kernels: what every other layer may use, and which imports nothing of swe_sphere but itself and the kernels.

Planets and constants, the errors (``errors.SweSphereError`` and its subclasses), the machine and
its backend (``runtime``: Warp, memory; ``backend``: the device and every choice that depends on
it; ``parallel``: CPU-thread launches and the launch recorder; ``graphs``: CUDA-graph capture with its check and fallback), MPI, process pools,
launch tallies and stop signals.

May import: nothing of swe_sphere outside ``core`` but ``swe_sphere.kernels``, the layer below
(``graphs``' bitwise check).
"""

__all__ = ["backend", "constants", "errors", "graphs", "interrupts", "mpi", "parallel", "runtime", "tally", "workers"]
