#!/usr/bin/env bash
# The package's own study commands (swe-sphere sweep, frontier, stability) whose tables the
# explanation pages quote, each rerun into benchmarks/results/cli_runs/<NAME>.csv (the command's
# own CSV, and a frontier's parts merged: one header, then their rows). One thread, CPU clock:
# the commands' own cost columns. Hours in all; name the ones to rerun:
#   bash benchmarks/studies/cli_runs.sh sweep_tc5_ne16_controlled stability_imex_pairs_ne8
#   bash benchmarks/studies/cli_runs.sh list
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=benchmarks/results/cli_runs
export SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

merged() { # NAME CSV... : the first file's header, then every file's rows, to $OUT/NAME.csv
    local name=$1; shift
    { head -n 1 "$1"; for f in "$@"; do tail -n +2 "$f"; done; } >"$work/$name.csv"
    mkdir -p "$OUT" && mv "$work/$name.csv" "$OUT/$name.csv"
}

frontier() { # NAME SCENE, then each part's --ne NE --np NP (kgu35, against T341, CPU clock)
    local name=$1 scene=$2 parts=() k=0; shift 2
    while [ $# -ge 2 ]; do
        k=$((k + 1))
        swe-sphere frontier "$scene" --ne "$1" --np "$2" --steppers kgu35 --reference T341 --cost cpu \
            --output "$work/$name.$k"
        parts+=("$work/$name.$k/frontier.csv"); shift 2
    done
    merged "$name" "${parts[@]}"
}

SWEEP_TC5="swe-sphere sweep tc5_mountain --ne 16 --np 4 --days 15"
TC5_LADDER=rk4@0.69,rk43@balance=0.1,rk43@balance=0.03,rk43@rtol=1e-5,rk43@rtol=7e-6,rk43@rtol=5e-6,rk43@rtol=1e-6,bs32@rtol=1e-5,bs32@rtol=2e-6
one() {
    case $1 in
    sweep_tc5_ne16_controlled) # docs: error_control, "the controller inside the sweep"
        $SWEEP_TC5 --output "$work/s" --runs "$TC5_LADDER"
        merged "$1" "$work/s/sweep.csv" ;;
    sweep_tc5_ne16_controlled_implicit)
        $SWEEP_TC5 --output "$work/s" --runs rk4@0.69,rk43@balance=0.1,rk43@rtol=5e-6,implicit@rtol=1e-4,implicit@rtol=1e-5
        merged "$1" "$work/s/sweep.csv" ;;
    sweep_galewsky_ne16_controlled)
        swe-sphere sweep galewsky --ne 16 --np 4 --days 6 --output "$work/g" \
            --runs fbrk32@1.3,rk43@balance=0.1,rk43@rtol=1e-3,rk43@rtol=1e-4,kgu352@rtol=1e-2
        merged "$1" "$work/g/sweep.csv" ;;
    stability_imex_pairs_ne8) # docs: error_control and reference, the IMEX pairs' Courant limits
        swe-sphere stability galewsky tc6_rossby_haurwitz tc5_mountain --steppers ark324,ark436,imex --output "$work/st"
        merged "$1" "$work/st/stability.csv" ;;
    frontier_tc5_issue99) # docs: frontier, "with the cheaper step"
        frontier "$1" tc5_mountain 8,16 3,4,5,6 8,12 7,8 ;;
    frontier_tc6_issue99)
        frontier "$1" tc6_rossby_haurwitz 4,8 3,4,5,6 16 3,4,5 4,8 7,8 ;;
    list)
        grep -oE '^    [a-z0-9_]+\)' "$0" | tr -d ' )' | grep -vx list ;;
    *)
        echo "cli_runs.sh: error: unknown name '$1' (bash $0 list)" >&2; exit 2 ;;
    esac
}

[ $# -ge 1 ] || { echo "usage: cli_runs.sh NAME... | list" >&2; exit 2; }
for name in "$@"; do one "$name"; done
