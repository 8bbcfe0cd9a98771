"""``swe-sphere sweep``: error against Δt against cost for several steppers."""

from __future__ import annotations

from .values import degree_band, numbers, overrides, restart_precision, runs, scene_overrides, steppers, varied


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
        overrides=scene_overrides(args) if args.branch_from is None else overrides(args.set),
        restart=args.branch_from,
        filter_days=args.filter_days,
        filter_every=args.filter_every,
        filter_window=args.filter_window,
    )
    if plan.checkpoint is not None:  # --from: the runs in the restart file's precision
        restart_precision(args.precision, plan.checkpoint.scene, args.branch_from)
    members = _members(args)
    device = pick_device(args.device)
    with executor(args.workers) as pool:
        if pool is None:  # an MPI worker rank: its share is done
            return 0
        output = args.output or plan.default_output
        plan.run(output, device, pool=pool, cost=args.cost, overwrite=args.overwrite, members=members)
    return 0


def _members(args):
    """``--members N`` with its one start (``--perturbation M [--seed S] [--perturbation-degrees
    L_MIN,L_MAX]``, ``--initial FILE`` or ``--vary KEY=V1,...``) as a ``studies.sweep.Members``, or
    None without them; ValueError for one without the other, two starts, or --seed or
    --perturbation-degrees without --perturbation."""
    from ..members.initial import MemberFile, Perturbation, Variants
    from ..studies.sweep import Members

    starts = {"--perturbation": args.perturbation, "--initial": args.initial, "--vary": args.vary}
    given = [flag for flag, value in starts.items() if value is not None]
    if args.members is None and not given:
        for flag, value in (("--seed", args.seed), ("--perturbation-degrees", args.perturbation_degrees)):
            if value is not None:
                raise ValueError(f"{flag} only with --members N --perturbation M")
        return None
    if args.members is None or not given:
        missing = "--members" if args.members is None else "--perturbation, --initial or --vary"
        raise ValueError(
            f"--members N and its start (--perturbation M, --initial FILE or --vary KEY=...) go together ({missing} missing)"
        )
    if len(given) > 1:
        raise ValueError(
            f"{' and '.join(given)}: the members start from one of a perturbation, --initial's file or --vary"
        )
    for flag, value in (("--seed", args.seed), ("--perturbation-degrees", args.perturbation_degrees)):
        if value is not None and given != ["--perturbation"]:
            raise ValueError(f"{flag} only with --members N --perturbation M")
    if args.perturbation is not None:
        degrees = None if args.perturbation_degrees is None else degree_band(args.perturbation_degrees)
        return Members(args.members, Perturbation(args.perturbation, args.seed or 0, degrees))
    return Members(args.members, MemberFile(args.initial) if args.initial is not None else Variants(varied(args.vary)))
