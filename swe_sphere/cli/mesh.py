"""``swe-sphere mesh``: write an Exodus II mesh (the cube, stretched, or refined over a box)."""

from __future__ import annotations

from .values import exodus_output

# bytes a mesh takes to make, write and measure: an element of the cube (its nodes, edges, the
# check, and its np 4 grid for the figures printed; measured 7.6-9.2 KB at ne 50 and 100), and a
# finest cell of a refined face (the cells' centres, turned, and their flags)
ELEMENT_BYTES, CELL_BYTES = 10_000, 64


def command(args) -> int:
    from ..grid.cubed_sphere import CubedSphere
    from ..grid.quality import element_sizes
    from ..grid.refine import Box, make_mesh
    from ..io.output_files import check_target
    from ..mesh.mesh import write_exodus

    exodus_output(args.output)
    _check_size(args)
    box = None if args.refine_box is None else Box(*args.refine_box)
    mesh = make_mesh(
        args.ne,
        stretch_factor=args.stretch_factor,
        target_lat=args.target_lat,
        target_lon=args.target_lon,
        box=box,
        levels=args.levels,
        smoothing=args.smoothing,
    )
    check_target(args.output, args.overwrite)  # after the options' own refusals (make_mesh's)
    write_exodus(args.output, mesh)
    sizes = element_sizes(CubedSphere(0, 4, 1.0, mesh=mesh)).summary()
    print(
        f"{args.output}: {mesh.name}: {mesh.nelem} elements, {mesh.nnodes} nodes; at np 4 the largest "
        f"Dinv-based distortion {sizes['distortion_max']:.2f}, area ratio {sizes['area_ratio']:.3g}"
    )
    return 0


def _check_size(args) -> None:
    """``ValueError`` (one line naming the option, exit 2) for a mesh whose making would take more
    memory than is available (``runtime.available_memory``): --ne's cube, or with --refine-box the
    finest cells of a face, ne 2^levels across, before any array is made."""
    from ..core.runtime import available_memory, gib

    if not args.ne >= 1:  # make_mesh's own refusal
        return
    need, what = 6 * args.ne**2 * ELEMENT_BYTES, f"--ne {args.ne}: a cube of {6 * args.ne**2:.3g} elements"
    if args.refine_box is not None and args.levels is not None and args.levels >= 1:
        across = args.ne * 2**args.levels
        need += across**2 * CELL_BYTES
        what = f"--levels {args.levels} on --ne {args.ne}: {across} x {across} finest cells a face"
    have = available_memory()
    if need > have:
        raise ValueError(f"{what} would need about {gib(need)} of memory to make; {gib(have)} is available")
