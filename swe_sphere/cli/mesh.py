"""``swe-sphere mesh``: write an Exodus II mesh (the cube, stretched, or refined over a box)."""

from __future__ import annotations

from .values import exodus_output


def command(args) -> int:
    from ..grid.cubed_sphere import CubedSphere
    from ..grid.quality import element_sizes
    from ..grid.refine import Box, make_mesh
    from ..io.output_files import check_target
    from ..mesh.mesh import write_exodus

    exodus_output(args.output)
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
