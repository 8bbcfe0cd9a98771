#!/usr/bin/env bash
# ISSUE 23 item 3: the GPU measurements, for a session that is lent a device.
# Run from the repository root on the GPU machine; each part writes <part>.txt
# (and tests.xml) under $OUT (default ./gpu_out) and is time-boxed, so that
# the parts fit the device tool's 10 min per command and 30 min per session:
#
#   benchmarks/gpu_session.sh setup tests          # ≈ 9 min: install, full suite on CUDA
#   benchmarks/gpu_session.sh agreement            # ≈ 6 min: TC5 ne16 5 days, every stepper, CUDA vs CPU
#   benchmarks/gpu_session.sh throughput graphs tc5 iterations   # ≈ 8 min
#
# With no part named it runs them all in that order (≈ 23 min). DEVICE=cpu
# NE_SMALL=1 runs the Python parts on the CPU on tiny grids (checks the script).
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-$PWD/gpu_out}
mkdir -p "$OUT"
PY=${PYTHON:-python}
DEVICE=${DEVICE:-cuda}
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
small=${NE_SMALL:-0}

run() {  # run <part> <seconds> <command...>: output to $OUT/<part>.txt, time-boxed
    local part=$1 limit=$2
    shift 2
    echo "== $part ($(date -u +%H:%M:%S), limit ${limit}s): $*" | tee -a "$OUT/session.log"
    local t0=$SECONDS
    timeout --signal=INT --kill-after=10 "$limit" "$@" >"$OUT/$part.txt" 2>&1
    local rc=$?
    echo "== $part: exit $rc after $((SECONDS - t0)) s" | tee -a "$OUT/session.log"
    tail -n 25 "$OUT/$part.txt"
}

part_setup() {
    { nvidia-smi; "$PY" -c "import warp as wp; wp.init(); print(wp.__version__, wp.get_cuda_devices())"; } >"$OUT/device.txt" 2>&1
    cat "$OUT/device.txt"
    # the machine reaches no index: install the checkout alone, against what is there. Its image had
    # no Warp, netCDF4, cftime or pyamg (2026-11-22): bring them as files and put them on PYTHONPATH
    # first (benchmarks/README.md, "On a GPU", says how they travelled)
    "$PY" -c "import warp, netCDF4, pyamg" || { echo "== setup: warp, netCDF4 or pyamg missing on this machine" | tee -a "$OUT/session.log"; exit 2; }
    run setup 120 "$PY" -m pip install --no-deps --no-build-isolation -e .
}

part_tests() {
    # the whole default suite on the CUDA device; a CUDA test that skips is a failure here
    run tests 540 "$PY" -m pytest -q -rs -p no:cacheprovider --junitxml="$OUT/tests.xml"
    if grep -q "SKIPPED.*needs a CUDA device" "$OUT/tests.txt"; then
        echo "== tests: CUDA tests skipped on the GPU machine" | tee -a "$OUT/session.log"
    fi
}

part_agreement() {  # explicit and large-step steppers apart, each within half the 10 min of a command
    if [ "$small" = 1 ]; then set -- --ne 2 --days 0.05; else set -- --ne 16 --days 5; fi
    run agreement 280 "$PY" benchmarks/gpu_session.py agreement --device "$DEVICE" "$@" --steppers leapfrog leapfrog_trapezoidal ssprk3 rk4
    run agreement_implicit 280 "$PY" benchmarks/gpu_session.py agreement --device "$DEVICE" "$@" --steppers semi_implicit imex implicit
}

part_throughput() {
    if [ "$small" = 1 ]; then set -- --ne 2 4 --copy-mib 8 --repeat 3; else set -- --ne 30 60 120 240; fi
    run throughput 180 "$PY" benchmarks/gpu_session.py throughput --device "$DEVICE" "$@"
}

part_graphs() {
    if [ "$small" = 1 ]; then set -- --ne 2 --repeat 2; else set -- --ne 30; fi
    run graphs 120 "$PY" benchmarks/gpu_session.py graphs --device "$DEVICE" "$@"
}

part_tc5() {
    local ne=120 days=1
    if [ "$small" = 1 ]; then ne=2 days=0.05; fi
    run tc5 180 "$PY" -m swe_sphere.cli run tc5_mountain --ne $ne --days $days --stepper ssprk3 --device "$DEVICE" \
        --no-progress --output "$OUT/tc5_ne${ne}.nc" --overwrite
}

part_iterations() {
    if [ "$small" = 1 ]; then set -- --ne 2 --steps 1; else set -- --ne 30; fi
    run iterations 180 "$PY" benchmarks/gpu_session.py iterations --device "$DEVICE" "$@"
}

parts=("$@")
[ ${#parts[@]} -eq 0 ] && parts=(setup tests agreement throughput graphs tc5 iterations)
for part in "${parts[@]}"; do
    case $part in
        setup|tests|agreement|throughput|graphs|tc5|iterations) "part_$part" ;;
        *) echo "unknown part '$part' (setup tests agreement throughput graphs tc5 iterations)" >&2; exit 2 ;;
    esac
done
