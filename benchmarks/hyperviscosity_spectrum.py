"""Damping of spherical harmonics by the model's ∇⁴ hyperviscosity.

For each grid and degree l, the Rayleigh quotient ⟨x, Bx⟩/⟨x, x⟩ of the
hyperviscosity operator B on a degree-l harmonic height, rotational wind and
divergent wind (``diagnostics.harmonic_state``), divided by HOMME's continuous
rate (``diagnostics.ideal_hyperviscosity_rate``: ν_s(l(l+1))²/a⁴,
ν(l(l+1) − 2)²/a⁴, (l(l+1) − 2)(ν_div l(l+1) − 2ν)/a⁴) and by the plain
ν(l(l+1)/a²)², and the e-folding rate per day at ν = nu.

    python benchmarks/hyperviscosity_spectrum.py [--grids 16x4 30x4] [--nu 1.5e15] [--nu-div X]
"""

import argparse

import numpy as np

from swe_sphere.constants import DAY
from swe_sphere.diagnostics import HARMONIC_KINDS, harmonic_state, hyperviscosity_rate, ideal_hyperviscosity_rate
from swe_sphere.grid import CubedSphere
from swe_sphere.model import ShallowWater


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--grids", nargs="+", default=["16x4", "30x4"], help="ne x np")
    p.add_argument("--degrees", nargs="+", type=int, default=[2, 4, 8, 16, 32, 48, 64, 100])
    p.add_argument("--nu", type=float, default=1.5e15, help="ν = ν_s (m^4/s)")
    p.add_argument("--nu-div", type=float, default=None, help="ν_div (m^4/s; default ν)")
    args = p.parse_args()
    nu = args.nu
    nu_div = nu if args.nu_div is None else args.nu_div
    for spec in args.grids:
        ne, np_ = map(int, spec.split("x"))
        g = CubedSphere(ne, np_)
        z = np.zeros(g.npts)
        m = ShallowWater(g, ["hyperviscosity"], z, z, nu=nu, nu_div=nu_div, nu_s=nu)
        print(f"\nne{ne} np{np_}: ν = {nu:.3g}, ν_div = {nu_div:.3g} m^4/s; per kind: rate/HOMME, rate/ν(l(l+1)/a²)², e-folds per day")
        print(f"{'l':>4} | " + " | ".join(f"{k:^27}" for k in HARMONIC_KINDS))
        for l in args.degrees:
            cells = []
            for kind in HARMONIC_KINDS:
                rate = hyperviscosity_rate(m, harmonic_state(g, l, kind))
                homme = ideal_hyperviscosity_rate(l, kind, nu, nu_div, nu, g.radius)
                plain = (nu_div if kind == "divergent" else nu) * (l * (l + 1) / g.radius**2) ** 2
                cells.append(f"{rate / homme:7.4f} {rate / plain:7.4f} {rate * DAY:9.3g}")
            print(f"{l:4d} | " + " | ".join(cells), flush=True)


if __name__ == "__main__":
    main()
