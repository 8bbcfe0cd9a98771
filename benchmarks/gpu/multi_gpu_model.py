"""A model of one TC5 RK4 step over P GPUs, one MPI rank each, its halo staged through host memory.

Prints, for each ne and GPU count, the time a step, the speed-up over one GPU and the parallel
efficiency, and, per GPU count, the smallest share of the grid a GPU must hold for a split to
pay (at all, and at 50 % parallel efficiency). Measured (benchmarks/gpu/GPU.md, one H100): a step's compute when bandwidth-bound (TC5 rk4
ne120, 1.06 ms a step over 86 400 elements, 12.3 ns an element), the floor of a step launched
plainly (142 µs at ne30: over several ranks no graphs) and as one graph (91 µs). Assumed
(labelled so in docs/explanation/scaling.md, section "GPUs"): each exchange's fixed cost through the host,
the PCIe copies' and the network's bandwidths and latencies.

    python benchmarks/gpu/multi_gpu_model.py                      # ne 30 60 120 240 480, 1 to 64 GPUs
    python benchmarks/gpu/multi_gpu_model.py --stage-us 20        # a faster exchange (CUDA-aware MPI, say)
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import positive, recorded

T_ELEMENT = 12.3e-9  # s an element a step, bandwidth-bound (H100, TC5 rk4 at ne120)
FLOOR_PLAIN = 142e-6  # s a step launched plainly (H100, TC5 rk4 at ne30): a run over ranks
FLOOR_GRAPH = 91e-6  # s a step as one CUDA graph (H100): a run on one GPU
EXCHANGES = 6  # a TC5 RK4 step's DSS exchanges (4 of 3 rows, 2 of the ∇⁴'s 4 rows)
ROWS = 20 / 6  # rows an exchange, on average
GPUS_A_NODE = 8  # an HGX/DGX H100 node


def ghosts(elements: float, np_: int = 4) -> float:
    """Copies a rank receives a DSS with ``elements`` elements (docs/explanation/scaling.md: ≈ 4·√E·np·1.2)."""
    return 4 * math.sqrt(elements) * np_ * 1.2


def step_time(ne: int, gpus: int, a) -> float:
    """Seconds a step of TC5 at ``ne`` (np 4) over ``gpus`` GPUs takes in the model."""
    elements = 6 * ne * ne
    if gpus == 1:
        return max(elements * T_ELEMENT, FLOOR_GRAPH)
    share = elements / gpus
    compute = max(share * T_ELEMENT, FLOOR_PLAIN)
    neighbours = min(gpus - 1, 8)
    nbytes = ghosts(share) * ROWS * 8
    copies = 2 * nbytes / (a.pcie_gbs * 1e9)  # device → host, host → device
    messages = neighbours * a.message_us * 1e-6
    if gpus > GPUS_A_NODE:  # some neighbours on other nodes: the network's latency and bandwidth
        messages += neighbours * a.net_latency_us * 1e-6 + nbytes / (a.net_gbs * 1e9)
    return compute + EXCHANGES * (a.stage_us * 1e-6 + copies + messages)


def smallest_ne(gpus: int, a, efficiency: float) -> int | None:
    """The smallest ne (to 8192) whose step on ``gpus`` GPUs is at least ``efficiency`` × gpus times as
    fast as on one (``efficiency`` 1 / gpus: faster at all); None where none is."""
    fast = (ne for ne in range(4, 8193) if step_time(ne, 1, a) >= efficiency * gpus * step_time(ne, gpus, a))
    return next(fast, None)


def tables(a) -> None:
    print("| ne | elements | " + " | ".join(f"{g} GPU{'s' if g > 1 else ''}" for g in a.gpus) + " |")
    print("|---:|---:|" + "---:|" * len(a.gpus))
    for ne in a.ne:
        one = step_time(ne, 1, a)
        cells = []
        for g in a.gpus:
            t = step_time(ne, g, a)
            cells.append(f"{1e3 * t:.2f} ms" + (f", {one / t:.1f}× ({one / t / g:.0%})" if g > 1 else ""))
        print(f"| {ne} | {6 * ne * ne} | " + " | ".join(cells) + " |")
    print("\nwhere a split pays: the smallest ne faster on P GPUs than on one, and the smallest at 50 % efficiency")
    print("| P | faster: ne | elements a GPU | 50 %: ne | elements a GPU | ne a GPU |")
    print("|---:|---:|---:|---:|---:|---:|")
    for g in (g for g in a.gpus if g > 1):
        faster, half = smallest_ne(g, a, 1 / g), smallest_ne(g, a, 0.5)
        share = [None if ne is None else 6 * ne * ne / g for ne in (faster, half)]
        text = ["–" if v is None else f"{v:,.0f}" for v in share]
        each = "–" if share[1] is None else f"{math.sqrt(share[1] / 6):.0f}"
        print(f"| {g} | {faster or '–'} | {text[0]} | {half or '–'} | {text[1]} | {each} |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ne", type=positive(int), nargs="+", default=[30, 60, 120, 240, 480])
    p.add_argument("--gpus", type=positive(int), nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    p.add_argument(
        "--stage-us", type=positive(float), default=35.0, help="an exchange's fixed cost through the host, µs"
    )
    p.add_argument("--message-us", type=positive(float), default=3.0, help="a further message in a node, µs")
    p.add_argument("--pcie-gbs", type=positive(float), default=25.0, help="a pinned copy's bandwidth, GB/s")
    p.add_argument("--net-latency-us", type=positive(float), default=2.0, help="a message's latency between nodes, µs")
    p.add_argument(
        "--net-gbs", type=positive(float), default=50.0, help="a GPU's network bandwidth (NDR 400 Gb/s), GB/s"
    )
    a = p.parse_args()
    with recorded(__file__):
        tables(a)


if __name__ == "__main__":
    main()
