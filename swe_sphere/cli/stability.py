"""``swe-sphere stability``: the largest stable Δt of each stepper on the hard cases."""

from __future__ import annotations

from .parser import STABILITY_NE
from .values import scene_overrides, steppers


def command(args) -> int:
    from ..core.backend import pick_device
    from ..core.workers import executor
    from ..io.output_files import check_results, folder_lock
    from ..studies import stability

    suite = stability.plan(
        args.cases,
        steppers(args.steppers),
        ne=STABILITY_NE if args.ne is None else args.ne,
        np_=args.np,
        days=args.days,
        mesh=args.mesh,
        overrides=scene_overrides(args),
    )
    device = pick_device(args.device)
    output = args.output or suite.default_output
    with executor(args.workers) as pool:
        if pool is None:  # an MPI worker rank: its share is done
            return 0
        with folder_lock(output, "stability.lock"):  # a second suite into this folder is refused now, not at its end
            check_results(output, stability.OUTPUTS, args.overwrite)  # an earlier suite's results: now, not at the end
            results = suite.run(device, pool=pool)
            print(stability.format_table(results))
            for path in stability.write_table(results, output, overwrite=args.overwrite):
                print(f"wrote {path}")
    return 0
