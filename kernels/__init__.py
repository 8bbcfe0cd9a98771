"""Warp kernels of swe_sphere (shipped as ``swe_sphere.kernels``).

One source for CPU and CUDA, float64. Fields are element-local and flat: node
``(e, i, j)`` at ``p = e*np*np + j*np + i`` (see ``swe_sphere.grid.cubed_sphere``); vector
and state fields are 2-D arrays ``(rows, N)``, the state's rows being
``u, v, h``. Kernels never import orchestration code.

Kernels launched over the nodes take a trailing ``offset: int``: the node a
thread handles is ``wp.tid() + offset`` (the last index of a 2-D tid), so that
``swe_sphere.core.parallel`` can run one launch as disjoint node ranges on several
CPU threads; pass 0 for a plain launch over all N nodes.
"""
