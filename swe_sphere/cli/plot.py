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
    from ..studies.plotting import plot_analyses, plot_run

    fields = args.field or ["h_surface"]
    if args.spectrum or args.zonal_mean:
        if args.diff is not None or args.force:
            raise ValueError("--diff and --force compare maps: not with --spectrum or --zonal-mean")
        if not args.zonal_mean and (args.field or args.lat_range):
            raise ValueError(
                f"--{'field' if args.field else 'lat-range'} applies to maps and --zonal-mean, not --spectrum"
            )
    _check_folder(args.output)  # after the options' own refusals
    if args.spectrum or args.zonal_mean:
        paths = plot_analyses(
            args.run,
            args.day,
            args.output,
            spectrum=args.spectrum,
            zonal_fields=fields if args.zonal_mean else (),
            lat_range=args.lat_range,
            overwrite=args.overwrite,
            member=args.member,
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
            overwrite=args.overwrite,
            member=args.member,
        )
    for path in paths:
        print(path)
    return 0
