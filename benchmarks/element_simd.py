"""Packed against scalar floating-point instructions in the CPU element kernels.

Compiles each per-element kernel (the CPU layout: ``tendency_element``,
``laplacian_element``, ``gradient_element``, ``divergence_element``,
``vorticity_element``, the Helmholtz operator's two element kernels) for one np
into the Warp kernel cache, disassembles its object file (``objdump -d``) and
counts, in the kernel's forward function, the arithmetic instructions on
packed doubles (``…pd``: add, sub, mul, div, sqrt, min, max, FMA; split by
register width, zmm/ymm/xmm) and on scalar doubles (``…sd``). Counts are static:
a loop Warp leaves rolled (the tendency's and the weak Laplacians' row and
field loops) counts its body once. Needs binutils' ``objdump``.

    python benchmarks/element_simd.py            # np 4
    python benchmarks/element_simd.py --np 4 8
"""

from __future__ import annotations

import argparse
import glob
import os
import re
import subprocess

import warp as wp

from swe_sphere.kernels import helmholtz, hyperviscosity, operators, tendencies

ARITHMETIC = re.compile(r"^v?(fn?m(?:add|sub)[0-9]+|mul|add|sub|div|sqrt|min|max)(p|s)d$")


def kernels(np_: int) -> dict:
    """Name → the element kernel for np_ (the TC5 term set and the ∇⁴'s passes)."""
    return {
        "tendency (5 terms)": tendencies.tendency_element(tendencies.TENDENCY_TERMS, np_),
        "tendency (continuity)": tendencies.tendency_element(("continuity",), np_),
        "laplacian_element first": hyperviscosity.laplacian_element(False, False, np_),
        "laplacian_element first, ν_div ≠ ν": hyperviscosity.laplacian_element(False, True, np_),
        "laplacian_element second": hyperviscosity.laplacian_element(True, False, np_),
        "gradient_element": operators.gradient_element(np_),
        "divergence_element": operators.divergence_element(np_),
        "vorticity_element": operators.vorticity_element(np_),
        "helmholtz_gradient": helmholtz.helmholtz_gradient(np_),
        "helmholtz_divergence (4 copies)": helmholtz.helmholtz_divergence(np_, 4),
    }


def count(obj: str) -> dict:
    """Packed (by register) and scalar double arithmetic in the forward function(s) of ``obj``."""
    text = subprocess.run(["objdump", "-d", "--no-show-raw-insn", obj], capture_output=True, text=True, check=True).stdout
    n = {"packed": 0, "zmm": 0, "ymm": 0, "xmm": 0, "scalar": 0}
    keep = False
    for line in text.splitlines():
        head = re.match(r"^[0-9a-f]+ <(.*)>:$", line)
        if head:
            keep = "forward" in head.group(1)
            continue
        fields = line.split("\t")
        if not keep or len(fields) < 2 or not fields[-1].strip():
            continue
        ins = fields[-1].strip()
        kind = ARITHMETIC.match(ins.split()[0])
        if kind and kind.group(2) == "s":
            n["scalar"] += 1
        elif kind:
            n["packed"] += 1
            n["zmm" if "zmm" in ins else "ymm" if "ymm" in ins else "xmm"] += 1
    return n


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--np", type=int, nargs="+", default=[4])
    args = parser.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    flags = operators.CPU_FAST["cpu_compiler_flags"]
    print(f"Warp {wp.__version__}, CPU flags: {flags}")
    for np_ in args.np:
        print(f"np = {np_}: FP arithmetic instructions in each kernel's forward function (static count)")
        print(f"  {'kernel':36s} {'packed':>6s} (zmm/ymm/xmm) {'scalar':>6s}")
        for name, kernel in kernels(np_).items():
            kernel.module.load("cpu")
            folder = os.path.join(wp.config.kernel_cache_dir, kernel.module.get_module_identifier())
            obj = max(glob.glob(os.path.join(folder, "*.o")), key=os.path.getmtime)
            n = count(obj)
            print(f"  {name:36s} {n['packed']:6d} ({n['zmm']}/{n['ymm']}/{n['xmm']}) {n['scalar']:10d}")


if __name__ == "__main__":
    main()
