"""Make the bundled reference files from the spectral model's full output.

    python testcases/reference/bundle.py SOURCE_DIR [DEST_DIR]

SOURCE_DIR holds the reference runs' spherical-harmonic coefficients as the
spectral model wrote them (float64, every output day; layout in this folder's
README). Each bundled file keeps only the days that are scored (``BUNDLE``), as
float32 (relative rounding 6e-8, far below any model error compared with them)
with zlib, and a title naming the case (``reference.stored_case``). DEST_DIR
defaults to this folder.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import xarray as xr

FIELDS = (
    "hfree_spec",
    "vort_spec",
    "div_spec",
)  # the T-truncated mountain (hs_spec) is left out: scoring uses the exact cone

# bundled file → (the case its title names, the days kept). T213: the days the
# earlier gridded files stored (tests and runs score at them); T341: the days the
# efficiency study scores (TC5 15, TC6 14, Galewsky 6) and TC5's day 1 for a quick
# check; TC2: its exact solution checks the evaluation (tests/cases/test_reference.py).
BUNDLE = {
    "tc5_mountain_T213.nc": ("tc5_mountain", (0, 1, 2, 5, 10, 15)),
    "tc6_rossby_haurwitz_T213.nc": ("tc6_rossby_haurwitz", (0, 1, 2, 7, 14)),
    "galewsky_T213.nc": ("galewsky", (0, 1, 2, 4, 5, 6)),
    "galewsky_balanced_T213.nc": ("galewsky_balanced", (0, 6)),
    "tc5_mountain_T341.nc": ("tc5_mountain", (1, 15)),
    "tc6_rossby_haurwitz_T341.nc": ("tc6_rossby_haurwitz", (14,)),
    "galewsky_T341.nc": ("galewsky", (6,)),
    "tc2_steady_alpha_pi4_T213.nc": ("tc2_steady", (5,)),
    "tc7_era_january_T213.nc": ("tc7_era_january", (0, 1, 2, 3, 4, 5)),
    "tc7_era_january_T341.nc": ("tc7_era_january", (0, 1, 2, 3, 4, 5)),  # case 7's default: its start and scored days
}


def bundle(source: Path, dest: Path, name: str) -> None:
    case, days = BUNDLE[name]
    with xr.open_dataset(source / name, decode_times=False) as ds:
        keep = [int(np.flatnonzero(np.abs(ds["time"].values - d) < 1e-9)[0]) for d in days]
        out = ds[["sh_l", "sh_m", *(f"{f}_{p}" for f in FIELDS for p in ("re", "im"))]].isel(time=keep).load()
        attrs = dict(ds.attrs)
    for f in FIELDS:
        for p in ("re", "im"):
            out[f"{f}_{p}"] = out[f"{f}_{p}"].astype(np.float32)
    truncation = f"T{int(attrs['lmax'])}"
    attrs["title"] = f"{truncation} spectral-transform reference solution: {case}"
    attrs["spectral_convention"] = attrs["spectral_convention"].replace("float64", "float32")
    attrs["bundled"] = (
        f"days {', '.join(map(str, days))} of the run, coefficients rounded to float32; "
        "the T-truncated mountain hs_spec left out (testcases/reference/bundle.py)"
    )
    out.attrs = attrs
    out["time"].attrs = {"units": "days", "long_name": "time since the initial condition"}
    encoding = {v: {"zlib": True, "complevel": 9, "shuffle": True} for v in out.data_vars}
    out.to_netcdf(dest / name, encoding=encoding)


def main(argv) -> None:
    source = Path(argv[0])
    dest = Path(argv[1]) if len(argv) > 1 else Path(__file__).parent
    for name in BUNDLE:
        bundle(source, dest, name)
        print(f"{name}: {(dest / name).stat().st_size / 2**20:.2f} MiB")


if __name__ == "__main__":
    main(sys.argv[1:])
