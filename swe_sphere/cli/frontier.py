"""``swe-sphere frontier``: error against cost over a ladder of grids and steppers, and its
Pareto front (``studies.frontier``)."""

from __future__ import annotations

from .values import integers, numbers, scene_overrides


def command(args) -> int:
    from ..core.backend import pick_device
    from ..core.workers import executor
    from ..studies import frontier

    plan = frontier.plan(
        args.scene,
        ne=integers(args.ne, "ne"),
        np_=integers(args.np, "np"),
        steppers=None if args.steppers is None else [s for s in args.steppers.split(",") if s],
        error=args.error,
        reference=args.reference,
        days=args.days,
        overrides=scene_overrides(args),
    )
    device = pick_device(args.device)
    targets = numbers(args.target, "target") if args.target else ()
    peers = frontier.read_peers(args.peers) if args.peers else ()  # refused before any run
    with executor(args.workers) as pool:
        if pool is None:  # an MPI worker rank: its share is done
            return 0
        plan.run(
            args.output or plan.default_output,
            device,
            pool=pool,
            cost=args.cost,
            targets=targets,
            overwrite=args.overwrite,
            peers=peers,
        )
    return 0
