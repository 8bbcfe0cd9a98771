"""An ensemble's run file opened (``Ensemble.run``): its attributes and ``RunWriter``."""

from __future__ import annotations

from ..io.run_file import OUTPUT_FIELDS, RunWriter


def member_writer(output, scene, grid, hs, attrs: dict, members: int, series, overwrite: bool, compress: bool, notify):
    """The ``RunWriter`` of ``members`` members of ``scene`` on ``grid`` (``hs`` (n,) m, one
    member's surface height) at ``output`` with ``attrs`` and the per-member ``series``; what its
    cells cost told to ``notify(line)`` (None: not told). ``OutputError`` as ``RunWriter``'s."""
    writer = RunWriter(
        output,
        grid,
        hs,
        attrs,
        ("steps", "wall_time"),
        overwrite=overwrite,
        compress=compress,
        fields=scene.output_fields or OUTPUT_FIELDS,
        cells=scene.output_cells,
        members=members,
        member_series=series,
    )
    if notify is not None:
        for line in writer.cells_notes(scene.grid_text):
            notify(line)
    return writer
