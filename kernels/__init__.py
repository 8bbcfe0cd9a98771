"""Warp kernels of swe_sphere (shipped as ``swe_sphere.kernels``).

One source for CPU and CUDA, float64. Fields are element-local and flat: node
``(e, i, j)`` at ``p = e*np*np + j*np + i`` (see ``swe_sphere.grid``); vector
and state fields are 2-D arrays ``(rows, N)``, the state's rows being
``u, v, h``. Kernels never import orchestration code.
"""
