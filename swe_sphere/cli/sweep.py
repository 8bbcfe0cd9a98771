"""``swe-sphere sweep``: error against Δt against cost for several steppers."""

from __future__ import annotations

from .values import numbers, overrides, runs, steppers


def command(args) -> int:
    from ..core.backend import pick_device
    from ..core.workers import executor
    from ..studies import sweep

    pairs = runs(args.runs) if args.runs is not None else None
    plan = sweep.plan(
        args.scene,
        steppers=None if args.steppers is None else steppers(args.steppers),
        dts=None if args.dt is None else numbers(args.dt, "dt"),
        courant=None if args.courant is None else numbers(args.courant, "courant"),
        runs=pairs,
        ne=args.ne,
        np_=args.np,
        days=args.days,
        overrides=overrides(args.set),
        restart=args.branch_from,
        filter_days=args.filter_days,
        filter_every=args.filter_every,
        filter_window=args.filter_window,
    )
    members = None
    if args.members is not None or args.perturbation is not None:
        given = [f for f, v in (("--members", args.members), ("--perturbation", args.perturbation)) if v is None]
        if given:
            raise ValueError(f"--members N and --perturbation M go together ({' and '.join(given)} missing)")
        members = sweep.Members(args.members, args.perturbation, 0 if args.seed is None else args.seed)
    elif args.seed is not None:
        raise ValueError("--seed only with --members N --perturbation M")
    device = pick_device(args.device)
    with executor(args.workers) as pool:
        if pool is None:  # an MPI worker rank: its share is done
            return 0
        output = args.output or plan.default_output
        plan.run(output, device, pool=pool, cost=args.cost, overwrite=args.overwrite, members=members)
    return 0
