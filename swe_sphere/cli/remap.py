"""``swe-sphere remap``: a run file on a regular lat-lon grid."""

from __future__ import annotations

from pathlib import Path

from .values import netcdf_output


def command(args) -> int:
    from ..io.output_files import check_distinct, check_target
    from ..io.remap import grid_name, latlon_grid, open_netcdf, remap_file, run_grid

    output = netcdf_output(args.output) or Path(f"{args.run.stem}_latlon{args.resolution:g}.nc")
    lat, lon = latlon_grid(args.resolution)
    check_distinct([output], [args.run])
    check_target(output, args.overwrite)
    with open_netcdf(args.run) as ds:
        grid = run_grid(ds)
    remap_file(args.run, args.resolution, output, overwrite=args.overwrite)
    print(f"{output}: {grid_name(grid)} -> {lat.size} x {lon.size} lat-lon points ({args.resolution:g} degrees)")
    return 0
