"""``swe-sphere remap``: a run file on a regular lat-lon grid."""

from __future__ import annotations

from pathlib import Path

from .values import netcdf_output


def command(args) -> int:
    from ..io.output_files import check_distinct, check_target
    from ..io.remap import check_remap_memory, grid_name, latlon_shape, open_netcdf, remap_file, run_grid

    output = netcdf_output(args.output) or Path(f"{args.run.stem}_latlon{args.resolution:g}.nc")
    latlon_shape(args.resolution)
    check_distinct([output], [args.run])
    check_target(output, args.overwrite)
    with open_netcdf(args.run) as ds:
        nlat, nlon = check_remap_memory(ds, args.resolution)  # before any work
        grid = run_grid(ds)
    remap_file(args.run, args.resolution, output, overwrite=args.overwrite)
    print(f"{output}: {grid_name(grid)} -> {nlat} x {nlon} lat-lon points ({args.resolution:g} degrees)")
    return 0
