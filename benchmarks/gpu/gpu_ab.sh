#!/usr/bin/env bash
# Two trees timed on the same card in one call, interleaved (a baseline beside a change: benchmarks/gpu/GPU.md).
# Each tree travels as its own copy of swe_sphere, kernels and benchmarks (git archive, 4 MB the pair),
# run with nothing installed: a script's own folder and PYTHONPATH decide what it imports.
#
#   bash benchmarks/gpu/gpu_ab.sh pack BASE [HEAD]     # here: .ab/base and .ab/head (default HEAD), git-ignored
#   bash benchmarks/gpu/gpu_ab.sh run ROUNDS SCRIPT [ARGS...]   # there, after the payload's third call has
#                                                  # unpacked ~/site; carry [".gpu3", ".ab"]
#
# `run` times benchmarks/SCRIPT (with its room: studies/control_ne30.py control_overhead) of each tree ROUNDS times, base then head, each with
# `--results ab_<tree>_r<round>` appended; each run's output in <tree>_r<round>.txt, all of
# them and the results files in $OUT/ab.tgz; AB_GREP (a grep -E pattern) picks the lines printed
# here, AB_LIMIT (s, default 120) bounds each run. Example (issue 83, 2026-11-27):
#   bash benchmarks/gpu/gpu_ab.sh run 3 studies/control_ne30.py control_overhead --device cuda --ne 60 --control error --pair rk43 \
#       --rtol 1e-6 --parts a --days 2
set -u
cd "$(dirname "$0")/../.."
case "${1:-}" in
pack)
    [ $# -ge 2 ] || { echo "usage: $0 pack BASE [HEAD]" >&2; exit 2; }
    grep -qx "/.ab/" .git/info/exclude 2>/dev/null || echo "/.ab/" >>.git/info/exclude
    rm -rf .ab
    for tree in base head; do
        rev=$2; [ $tree = head ] && rev=${3:-HEAD}
        mkdir -p .ab/$tree && git archive "$rev" swe_sphere kernels benchmarks | tar -x -C .ab/$tree || exit 2
        rm -rf .ab/$tree/benchmarks/results && mkdir .ab/$tree/benchmarks/results
        ln -s ../../../testcases .ab/$tree/swe_sphere/testcases  # the checkout's (13 MB travels once)
        echo "$tree: $(git rev-parse --short "$rev")" | tee -a .ab/trees.txt
    done
    du -sh .ab ;;
run)
    [ $# -ge 3 ] || { echo "usage: $0 run ROUNDS SCRIPT [ARGS...]" >&2; exit 2; }
    rounds=$2 script=$3; shift 3
    out=${OUT:-$PWD/ab_out} work=$(mktemp -d)
    mkdir -p "$out"
    export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 PYTHONUNBUFFERED=1
    cat .ab/trees.txt; uptime
    for tree in base head; do  # -P: what a script imports (-c alone would put the checkout first)
        PYTHONPATH=$PWD/.ab/$tree:$HOME/site python3 -P -c "import swe_sphere; print('$tree imports', swe_sphere.__file__)"
    done
    for r in $(seq 1 "$rounds"); do
        for tree in base head; do
            log=$work/${tree}_r$r.txt
            PYTHONPATH=$PWD/.ab/$tree:$HOME/site timeout "${AB_LIMIT:-120}" \
                python3 ".ab/$tree/benchmarks/$script" "$@" --results "ab_${tree}_r$r" >"$log" 2>&1
            echo "$tree r$r (exit $?): $(grep -E "${AB_GREP:-.}" "$log" | tail -n 8 | tr -s ' ' | tr '\n' '|')"
        done
    done
    uptime
    cp .ab/*/benchmarks/results/*/ab_* "$work"/ 2>/dev/null
    tar czf "$out/ab.tgz" -C "$work" . ;;
*)
    echo "usage: $0 pack BASE [HEAD] | run ROUNDS SCRIPT [ARGS...]" >&2; exit 2 ;;
esac
