"""``swe-sphere plot``: PNG maps of a run file, or its spectrum or zonal means."""

from __future__ import annotations

import os
from pathlib import Path

from ..core.errors import OutputError


def _check_folder(folder: Path) -> None:
    """Raise ``OutputError`` in run/remap/mesh's words when the PNGs' folder, or the
    folder it would be made in, cannot be written (``os.access``: a read-only file
    system included), or is named as an image file is (``x.png``: not made as a folder)."""
    if folder.suffix.lower() in (".png", ".pdf", ".svg") and not folder.is_dir():  # a file's name, not a folder's
        raise OutputError(f"--output {folder}: the folder the PNGs go in (each named by its field and day), not a file")
    existing = folder.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if existing.is_dir() and not os.access(existing, os.W_OK):
        raise OutputError(f"output directory is not writable: {existing}")


def command(args) -> int:
    from ..studies.analysis_plots import plot_analyses
    from ..studies.animation import animate_run, check_format
    from ..studies.plotting import figure_size, plot_run

    fields = args.field or ["h_surface"]
    if args.width is not None:
        if args.spectrum or args.zonal_mean:
            raise ValueError(f"--width sizes maps: not with --{'spectrum' if args.spectrum else 'zonal-mean'}")
        figure_size(args.width)
    if args.animate is not None:
        given = [
            f for f, v in (("--diff", args.diff), ("--spectrum", args.spectrum), ("--zonal-mean", args.zonal_mean)) if v
        ]
        if given or args.force:
            raise ValueError(f"{' and '.join(given or ['--force'])}: not with --animate (a field's maps over time)")
        if len(fields) > 1:
            raise ValueError(f"--animate draws one --field (got {' '.join(fields)})")
        check_format(args.animate)
    elif args.spectrum or args.zonal_mean:
        if args.diff is not None or args.force:
            raise ValueError("--diff and --force compare maps: not with --spectrum or --zonal-mean")
        if not args.zonal_mean and (args.field or args.lat_range):
            raise ValueError(
                f"--{'field' if args.field else 'lat-range'} applies to maps and --zonal-mean, not --spectrum"
            )
    _check_folder(args.output)  # after the options' own refusals
    view = {"overwrite": args.overwrite, "member": args.member}
    if args.animate is not None:
        paths = [
            animate_run(
                args.run, fields[0], args.day, args.output, args.lat_range, fmt=args.animate, width=args.width, **view
            )
        ]
    elif args.spectrum or args.zonal_mean:
        paths = plot_analyses(
            args.run,
            args.day,
            args.output,
            spectrum=args.spectrum,
            zonal_fields=fields if args.zonal_mean else (),
            lat_range=args.lat_range,
            **view,
        )
    else:
        paths = plot_run(
            args.run,
            fields,
            args.day,
            args.diff,
            args.output,
            args.lat_range,
            force=args.force,
            width=args.width,
            **view,
        )
    for path in paths:
        print(path)
    return 0
