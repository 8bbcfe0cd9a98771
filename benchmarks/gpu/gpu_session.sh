#!/usr/bin/env bash
# ISSUE 23 item 3 and ISSUE 32 items 2, 4, 5: the GPU measurements, for a session that is lent a device.
# Run from the repository root on the GPU machine; each part writes <part>.txt
# (and tests.xml) under $OUT (default ./gpu_out) and is time-boxed, so that
# the parts fit the device tool's 10 min per command and 30 min per session:
#
#   benchmarks/gpu/gpu_session.sh setup tests          # ≈ 9 min: install, the graph fallbacks, full suite on CUDA
#   benchmarks/gpu/gpu_session.sh agreement            # ≈ 6 min: TC5 ne16 5 days, every stepper, CUDA vs CPU
#   benchmarks/gpu/gpu_session.sh throughput graphs tc5 iterations   # ≈ 9 min
#   benchmarks/gpu/gpu_session.sh reads                 # ≈ 1 min: host reads a step, every stepper (ISSUE 32)
#   benchmarks/gpu/gpu_session.sh tests_gpu bits        # ≤ 4 + 2.5 min: the CUDA tests alone; graphs against plain launches, bitwise (issue 67)
#   benchmarks/gpu/gpu_session.sh study                 # ≤ 9 min: the ne30 TC5 study's runs on the GPU (ISSUE 32)
#   benchmarks/gpu/gpu_session.sh study_fine            # ≤ 9 min a call: TC5, TC6, Galewsky at ne60 and ne120
#   benchmarks/gpu/gpu_session.sh criterion_ne60        # ≤ 5 min: TC5 ne60, each family down to the 10 % criterion
#   benchmarks/gpu/gpu_session.sh criterion_ne120       # ≤ 7 min: TC5 ne120, kgu35, rk4 and imex
#   benchmarks/gpu/gpu_session.sh dinosaur              # ≤ 8 min: the peer Dinosaur (JAX) beside swe_sphere on the card
#   benchmarks/gpu/gpu_session.sh control               # ≤ 3.5 min: TC5 ne60 rk43 under error control, graphs against none (issue 64; CONTROL_DAYS, CONTROL_GRAPHS)
#   benchmarks/gpu/gpu_session.sh small                 # ≈ 1 min: galewsky and TC5 ne30 one day, ms a step (issue 83 item 5)
#   benchmarks/gpu/gpu_session.sh floor                 # ≈ 1 min: where a small grid's step goes: the run's loop, a graph a step, k steps a graph
#   benchmarks/gpu/gpu_session.sh kernels               # ≈ 1 min: each kernel's device time a step, galewsky and TC5 ne30, ne120
#   benchmarks/gpu/gpu_session.sh ensemble              # ≈ 1 min: galewsky, 32 members in the same launches against one (issue 85)
#   benchmarks/gpu/gpu_session.sh mpi                   # ≤ 5 min: 2 ranks sharing the card against 1: run files, a DSS, a gradient (issue 101)
#   benchmarks/gpu/gpu_session.sh exchange              # ≈ 2 min: the staged exchange's cost at ne30/60/120, 2 ranks on the card (issue 101)
#   benchmarks/gpu/gpu_session.sh card                  # ≤ 6.7 min (CARD_S), first on a card (issue 114 item 7): float32 against float64 (TC5
#                                                   # ne120, galewsky, TC5 ne30 and ne8, 32 galewsky members), then issue 101's
#                                                   # mpi and exchange; $OUT/card.json, card.md, card.tgz (CARD, CARD_S)
#
# With no part named it runs setup to iterations in that order (≈ 23 min); reads,
# study and study_fine are named. The studies are `swe-sphere sweep --device cuda
# --cost wall` into $STUDY (default ./gpu_study, git-ignored): a sweep stopped by its
# time box keeps its finished runs, and the same part run again (in the same
# machine's checkout, or with gpu_study carried to a fresh one) makes only the rest;
# each call copies the study folders to $OUT. DEVICE=cpu NE_SMALL=1 runs the Python
# parts and the studies on the CPU on tiny grids (checks the script). Every part named runs; the
# status is 1 when any of them failed or ran out of its time box (session.log names them).
set -u
cd "$(dirname "$0")/../.."
OUT=${OUT:-$PWD/gpu_out}
mkdir -p "$OUT"
PY=${PYTHON:-python}
DEVICE=${DEVICE:-cuda}
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 PYTHONUNBUFFERED=1  # a part stopped by its time box keeps the lines it printed
small=${NE_SMALL:-0}
STUDY=${STUDY:-$PWD/gpu_study}
[ "$DEVICE" = cpu ] && export SWE_SPHERE_THREADS=1  # graphs on a CPU need one thread a launch

failed=""  # the parts whose command failed or ran out of its time box
run() {  # run <part> <seconds> <command...>: output to $OUT/<part>.txt, time-boxed
    local part=$1 limit=$2
    shift 2
    echo "== $part ($(date -u +%H:%M:%S), limit ${limit}s): $*" | tee -a "$OUT/session.log"
    local t0=$SECONDS
    timeout --signal=INT --kill-after=10 "$limit" "$@" >"$OUT/$part.txt" 2>&1
    local rc=$?
    [ $rc -eq 0 ] || failed="$failed $part"
    echo "== $part: exit $rc after $((SECONDS - t0)) s" | tee -a "$OUT/session.log"
    tail -n 25 "$OUT/$part.txt"
}

part_setup() {
    { nvidia-smi; "$PY" -c "import warp as wp; wp.init(); print(wp.__version__, wp.get_cuda_devices())"; } >"$OUT/device.txt" 2>&1
    cat "$OUT/device.txt"
    # the machine reaches no index: install the checkout alone, against what is there. Its image had
    # no Warp, netCDF4, cftime or pyamg (2026-11-22): bring them as files and put them on PYTHONPATH
    # first (benchmarks/gpu/GPU.md says how they travel)
    "$PY" -c "import warp, netCDF4, ducc0, pyamg" || { echo "== setup: warp, netCDF4, ducc0 or pyamg missing on this machine" | tee -a "$OUT/session.log"; exit 2; }
    run setup 120 "$PY" -m pip install --no-deps --no-build-isolation -e .
}

part_tests_gpu() {  # issue 67 item 1 first: every CUDA test (slow ones too), one worker a GPU-sharing process
    run tests_gpu "${TESTS_GPU_S:-240}" "$PY" -m pytest -q -rs -p no:cacheprovider -m gpu -n "${TESTS_GPU_N:-6}" --junitxml="$OUT/tests_gpu.xml"
    grep -q "SKIPPED.*needs a CUDA device" "$OUT/tests_gpu.txt" && echo "== tests_gpu: CUDA tests skipped on the GPU machine" | tee -a "$OUT/session.log"
}

part_tests() {
    # first the graph fallbacks' CUDA twins (issue 44): the paths a GPU user's first run takes
    run tests_graph_fallback 60 "$PY" -m pytest -q -rs -p no:cacheprovider tests/core/test_graph_fallback.py
    # the whole default suite on the GPU machine (the CUDA tests on the card; the rest on its CPU,
    # the suite's SWE_SPHERE_DEVICE=cpu); a CUDA test that skips is a failure here. Then the
    # commands of the docs and the first hour on the card, as a GPU user's first runs
    # (SWE_SPHERE_DEVICE=cuda: the device of every run that names none)
    run tests 420 "$PY" -m pytest -q -rs -p no:cacheprovider --junitxml="$OUT/tests.xml"
    run tests_first_runs 180 env SWE_SPHERE_DEVICE=cuda "$PY" -m pytest -q -rs -p no:cacheprovider \
        tests/test_docs_examples.py tests/cli/test_run_names_and_locks.py
    if grep -q "SKIPPED.*needs a CUDA device" "$OUT/tests_graph_fallback.txt" "$OUT/tests.txt"; then
        echo "== tests: CUDA tests skipped on the GPU machine" | tee -a "$OUT/session.log"
    fi
}

part_agreement() {  # explicit and large-step steppers apart, each within half the 10 min of a command
    if [ "$small" = 1 ]; then set -- --ne 2 --days 0.05; else set -- --ne 16 --days 5; fi
    run agreement 280 "$PY" benchmarks/gpu/gpu_session.py agreement --device "$DEVICE" "$@" --steppers leapfrog leapfrog_trapezoidal ssprk3 rk4
    run agreement_implicit 280 "$PY" benchmarks/gpu/gpu_session.py agreement --device "$DEVICE" "$@" --steppers semi_implicit imex implicit
}

part_throughput() {
    if [ "$small" = 1 ]; then set -- --ne 2 4 --copy-mib 8 --repeat 3; else set -- --ne 30 60 120 240; fi
    run throughput 180 "$PY" benchmarks/gpu/gpu_session.py throughput --device "$DEVICE" "$@"
}

part_graphs() {  # ISSUE 32 target: an explicit TC5 ne30 step <= 0.12 ms
    if [ "$small" = 1 ]; then set -- --ne 2 --graph-steps 20 --runs 2; else set -- --ne 30 --graph-steps "${GRAPH_STEPS:-2000}" --runs "${GRAPH_RUNS:-5}"; fi
    run graphs 240 "$PY" benchmarks/gpu/gpu_session.py graphs --device "$DEVICE" "$@"
}

part_bits() {  # issue 67 item 2: graphs against plain launches, bitwise, every stepper, TC5 ne30 10 steps
    if [ "$small" = 1 ]; then set -- --ne 2; else set -- --ne 30; fi
    run bits 150 "$PY" benchmarks/gpu/gpu_session.py bits --device "$DEVICE" "$@"
}

part_reads() {  # ISSUE 32 target: 0 host reads in an explicit, IMEX or semi-implicit step
    if [ "$small" = 1 ]; then set -- --ne 2 --steps 1; else set -- --ne 30; fi
    run reads 120 "$PY" benchmarks/gpu/gpu_session.py reads --device "$DEVICE" "$@"
}

# the study's contenders (docs/explanation/efficiency.md, "The verdict"): each explicit stepper at its
# largest stable multiple of the gravity-wave limit Δt_g and half of it, and the implicit-type ones
R30=leapfrog_trapezoidal@0.64,leapfrog_trapezoidal@0.32,ssprk3@0.8,ssprk3@0.4,rk4@1.24,rk4@0.62,rk4@0.8,kgu35@1.6,kgu35@0.8,fbrk32@1.24,fbrk32@0.62
I30=semi_implicit@1,semi_implicit@2,imex@1,imex@2,imex@5,imex@10,imex@20,implicit@2,implicit@5,implicit@10,implicit@20
# TC6 and Galewsky: 0.9x the ne16 stability table's multiples (as at ne30) and their halves
R_TC6=leapfrog_trapezoidal@0.549,leapfrog_trapezoidal@0.275,ssprk3@0.702,ssprk3@0.351,rk4@1.09,rk4@0.545,kgu35@1.48,kgu35@0.738,fbrk32@1.04,fbrk32@0.522
R_GAL=leapfrog_trapezoidal@0.63,leapfrog_trapezoidal@0.315,ssprk3@0.81,ssprk3@0.405,rk4@1.25,rk4@0.626,kgu35@1.67,kgu35@0.837,fbrk32@1.25,fbrk32@0.626

sweep() {  # sweep <name> <seconds> <case> <ne> <days> <filter days> <runs>: one study, time-boxed, resumable
    local name=$1 limit=$2 case=$3 ne=$4 days=$5 filter=$6 runs=$7
    if [ "$small" = 1 ]; then ne=2 days=1 filter=0.5; fi  # day 1: a day the T341 files hold
    run "$name" "$limit" "$PY" -m swe_sphere.cli sweep "$case" --ne "$ne" --np 4 --days "$days" --filter-days "$filter" \
        --runs "$runs" --device "$DEVICE" --cost wall -s case.reference=T341 --output "$STUDY/$name"
    # at most 8 files come back from a call: the table alone (the summary is in $OUT/<name>.txt)
    [ -f "$STUDY/$name/sweep.csv" ] && cp "$STUDY/$name/sweep.csv" "$OUT/$name.csv"
}

part_study() {  # ISSUE 32 target: the ne30 TC5 study (15 days) in <= 10 minutes on one GPU
    sweep tc5_ne30 540 tc5_mountain 30 15 2 "$R30,$I30"
}

part_study_ne60() {  # issue 67 item 4 in one call: TC5 ne60 15 days, the verdict's contenders at their best multiples
    sweep tc5_ne60_best "${STUDY_S:-240}" tc5_mountain 60 15 2 \
        leapfrog_trapezoidal@0.64,ssprk3@0.8,rk4@1.24,kgu35@1.6,fbrk32@1.24,semi_implicit@2,imex@8
}

# issue 67 item 4: the ne60 verdict's cost at the 10 % criterion (the earlier ne60 call ran each family
# at its ne30 multiple only; four of them blew up there): each family at half that and below
part_criterion_ne60() {
    sweep tc5_ne60_criterion "${STUDY_S:-300}" tc5_mountain 60 15 2 \
        kgu35@0.8,kgu35@0.4,rk4@0.62,rk4@0.4,fbrk32@0.62,ssprk3@0.4,leapfrog_trapezoidal@0.32,semi_implicit@1,imex@2
}

# issue 67 item 4 at ne120: the cheapest explicit contenders and IMEX (the small-dt RK4 run,
# a quarter of 0.75 Δt_g, is most of the call)
part_criterion_ne120() {
    sweep tc5_ne120_criterion "${STUDY_S:-420}" tc5_mountain 120 15 2 kgu35@1.5,kgu35@0.75,rk4@0.75,imex@8
}

# issue 67 item 4: the peer Dinosaur (JAX, the image's CUDA plugin; its wheels in the payload) on the
# same card in the same call, both models' wall seconds a simulated day (benchmarks/peers/peer_dinosaur.py)
part_control() {  # issue 64/67/83: a controlled run's steps as CUDA graphs (one a grid dt, tries launched ahead) against a fixed dt
    for g in ${CONTROL_GRAPHS:-auto off}; do
        for d in ${CONTROL_DAYS:-0.25}; do  # issue 83 measured 0.25 and 2 days, three rounds each
            run "control_${g}_${d}d" 100 env SWE_SPHERE_GRAPHS=$g "$PY" benchmarks/studies/control_ne30.py control_overhead --device "$DEVICE" \
                --ne "$([ "$small" = 1 ] && echo 4 || echo 60)" --control error --pair rk43 --rtol 1e-6 --days "$d" \
                --parts a b --repeat 20 --results "gpu_control_overhead_${g}_${d}d"
        done
    done
    cp benchmarks/results/control_ne30/control_overhead/gpu_control_overhead_*.json "$OUT/" 2>/dev/null
}

part_small() {  # issue 83 item 5: the default scenes' step on the card, where launches bound it (target <= 0.05 ms)
    local args="--days 1"
    [ "$small" = 1 ] && args="--ne 2 --days 0.05"
    mkdir -p "$STUDY"
    for scene in galewsky tc5_mountain; do
        run "small_$scene" 120 "$PY" -m swe_sphere.cli run "$scene" $args --device "$DEVICE" --no-progress \
            --output "$STUDY/small_$scene.nc" --overwrite
    done
}

part_dinosaur() {
    local t="--truncations T42 T85 T170 T213"
    # Δt at a fraction of kgu35's measured limit on each grid (peer_dinosaur.py's STEPPER@F), the
    # fraction the grid has run to the end at: TC5 ne16 at 0.8 (the frontier's), ne30 at 0.75 (1.6 Δt_g,
    # docs/explanation/efficiency/multirate.md), ne60 at 0.65 (1.43 Δt_g ran 15 days there; 0.8 = 86400/375 blew up at
    # day 2.6 on an H100, issue 83); Galewsky the case's rows (the scene's ne12 np8 and its neighbours)
    run dinosaur_galewsky "${PEER_S:-240}" "$PY" benchmarks/peers/peer_dinosaur.py --case galewsky --device "$DEVICE" \
        --python "$PY" $t --results gpu_peer_dinosaur_galewsky
    run dinosaur_tc5 "${PEER_S:-240}" "$PY" benchmarks/peers/peer_dinosaur.py --case tc5 --device "$DEVICE" \
        --python "$PY" $t --results gpu_peer_dinosaur_tc5 \
        --swe ne16/np4/kgu35@0.8 ne30/np4/kgu35@0.75 ne60/np4/kgu35@0.65
    cp benchmarks/results/peer_dinosaur/gpu_peer_dinosaur_*.json "$OUT/" 2>/dev/null
}

# ISSUE 32 item 5: every contender at ne60 and ne120; repeat the part until every sweep ends. A run
# is kept only when it ends: one longer than a call's box (likely CN @ 2 Δt_g at ne120, 15 days at
# 40-90 ms a step) never completes here and needs a longer device slot
part_study_fine() {
    local t0=$SECONDS left
    for spec in "tc5_ne60 tc5_mountain 60 15 2 $R30,$I30" "tc6_ne60 tc6_rossby_haurwitz 60 14 2 $R_TC6,$I30" \
                "galewsky_ne60 galewsky 60 6 1 $R_GAL,$I30" "tc5_ne120 tc5_mountain 120 15 2 $R30,$I30" \
                "tc6_ne120 tc6_rossby_haurwitz 120 14 2 $R_TC6,$I30" "galewsky_ne120 galewsky 120 6 1 $R_GAL,$I30"; do
        set -- $spec
        [ -f "$STUDY/$1/summary.done" ] && continue
        left=$((540 - (SECONDS - t0)))
        [ "$left" -lt 30 ] && break
        sweep "$1" "$left" "$2" "$3" "$4" "$5" "$6" && grep -q "^wrote" "$OUT/$1.txt" && touch "$STUDY/$1/summary.done"
    done
}

part_tc5() {  # issue 67 target: TC5 ne120, 15 days, the scene's own stepper and Δt, >= 20 000 simulated days a wall day
    local ne=120 days=15
    if [ "$small" = 1 ]; then ne=2 days=0.05; fi
    mkdir -p "$STUDY"
    # as a user's first run: the BLAS and OpenMP threads the host's own (issue 83 item 4: the run file's
    # cells no longer spin on a many-core host), the process's CPU beside its wall time
    run tc5 180 env -u OMP_NUM_THREADS -u OPENBLAS_NUM_THREADS bash -c 'TIMEFORMAT="process: wall %R s, user %U s, sys %S s"; time "$@"' _ \
        "$PY" -m swe_sphere.cli run tc5_mountain --ne $ne --days $days --device "$DEVICE" \
        --no-progress --output "$STUDY/tc5_ne${ne}.nc" --overwrite
}

part_floor() {  # issue 83 item 5: is a small grid's step the host's (the run's loop) or the launches' own?
    if [ "$small" = 1 ]; then set -- --ne 2 --graph-steps 20 --runs 2; else set -- --ne 8 30; fi
    run floor 120 "$PY" benchmarks/gpu/gpu_session.py floor --device "$DEVICE" "$@"
}

part_kernels() {  # issue 83 items 5 and the ne120 target: which kernels a step's device time goes to
    if [ "$small" = 1 ]; then set -- --ne 2 --steps 2; else set -- --ne 30 120; fi
    run kernels 120 "$PY" benchmarks/gpu/gpu_session.py kernels --device "$DEVICE" "$@"
}

part_ensemble() {  # issue 85: on an H100, 32 galewsky members <= 4x one member's wall time
    if [ "$small" = 1 ]; then set -- --members 2 --steps 2 --rounds 1; else set -- --members "${MEMBERS:-32}" --steps 200 --rounds 3; fi
    run ensemble 150 "$PY" benchmarks/micro/ensemble_cost.py --scene galewsky --device "$DEVICE" --results gpu_ensemble_cost "$@"
    cp benchmarks/results/ensemble_cost/gpu_ensemble_cost.json "$OUT/" 2>/dev/null
}

part_iterations() {
    if [ "$small" = 1 ]; then set -- --ne 2 --steps 1; else set -- --ne 30; fi
    run iterations 180 "$PY" benchmarks/gpu/gpu_session.py iterations --device "$DEVICE" "$@"
}

mpi_env() {  # the payload's mpich wheel (unpacked into PYTHONPATH's first folder): its programs executable, found
    command -v mpiexec >/dev/null && return 0
    local d
    d=$(ls -d "${PYTHONPATH%%:*}"/mpich-*.data/data 2>/dev/null | head -n 1)
    if [ -z "$d" ]; then
        echo "== mpi: no mpiexec here and no mpich in the payload (bash benchmarks/gpu/gpu_payload.sh)" | tee -a "$OUT/session.log"
        failed="$failed mpi"
        return 1
    fi
    chmod +x "$d"/bin/*  # a wheel unpacked by zipfile keeps no modes
    export PATH="$d/bin:$PATH" LD_LIBRARY_PATH="$d/lib:${LD_LIBRARY_PATH:-}" MPI4PY_LIBMPI="$d/lib/libmpi.so.12"
}

part_mpi() {  # issue 101: 2 ranks sharing the card against 1 (run files, a DSS, a gradient; test_mpi_devices.py)
    # [LIMIT] [PYTEST ARGS...]: the card part's time box and a choice of its tests
    local limit=${1:-300}
    shift $(($# > 0))
    mpi_env || return 0
    run mpi "$limit" "$PY" -m pytest -q -rs -p no:cacheprovider -n 0 --junitxml="$OUT/mpi.xml" tests/test_mpi_devices.py "$@"
    if [ "$DEVICE" != cpu ] && grep -q "SKIPPED" "$OUT/mpi.txt"; then
        echo "== mpi: tests skipped on the GPU machine" | tee -a "$OUT/session.log"
        failed="$failed mpi"
    fi
}

part_exchange() {  # issue 101: a step and the bare staged exchange on 1 and 2 ranks of the card (benchmarks/studies/scaling.py)
    local limit=${1:-240}  # [LIMIT]: the card part's time box
    mpi_env || return 0
    if [ "$small" = 1 ]; then set -- --ne 4 --steps 3; else set -- --ne ${EXCHANGE_NE:-30 60 120} --steps 50; fi
    run exchange "$limit" "$PY" benchmarks/studies/scaling.py --device "$DEVICE" --ranks 1 2 --model-ranks --repeat "${ROUNDS:-1}" \
        --results "$OUT/exchange" "$@"
}

# issue 114 item 7: float32 against float64 on the card, then what issues 99 and 101 left for one, each
# item time-boxed and all within CARD_S (default 400 s: the device tool's 10 min a command with the
# setup and a margin); CARD names the items to run (default all, in this order: the most important
# first). Their output under $OUT/card/, bundled at the end as $OUT/card.tgz (at most 8 files come
# back from a call) beside card.json and card.md, the summary (`gpu_session.py card`)
part_card() {
    local deadline=$((SECONDS + ${CARD_S:-400})) item limit left outer=$OUT
    local OUT=$OUT/card  # run() and the parts write here
    mkdir -p "$OUT"
    local p="$PY benchmarks/gpu/gpu_session.py precision --device $DEVICE"
    for item in ${CARD:-tc5_ne120 state galewsky small members mpi exchange}; do
        case $item in  # the item's time box, its command's grids and steps (NE_SMALL: tiny, on a CPU)
            tc5_ne120) limit=180 ;; state|galewsky|small) limit=60 ;; members) limit=90 ;; mpi) limit=150 ;; exchange) limit=120 ;;
            *) echo "== card: unknown item '$item' (tc5_ne120 state galewsky small members mpi exchange)" | tee -a "$OUT/session.log"
               failed="$failed card"; continue ;;
        esac
        left=$((deadline - SECONDS))
        if [ "$left" -lt 30 ]; then
            echo "== card: $item not run, CARD_S spent" | tee -a "$OUT/session.log"
            failed="$failed $item"
            continue
        fi
        [ "$limit" -gt "$left" ] && limit=$left
        local r="--results $OUT/precision_$item"
        case $item in
            tc5_ne120) if [ "$small" = 1 ]; then set -- --ne 2 --warmup 3 --graph-steps 2 --runs 2; else set -- --ne 120 --warmup 100 --graph-steps 1000 --runs 5; fi
                run "precision_$item" "$limit" $p --scene tc5_mountain $r --chain --target-days 80000 "$@" ;;
            state) if [ "$small" = 1 ]; then set -- --ne 2 --warmup 3 --graph-steps 2 --runs 2; else set -- --ne 120 --warmup 100 --graph-steps 1000 --runs 3; fi
                run "precision_$item" "$limit" $p --scene tc5_mountain $r --precisions float64 float32_state "$@" ;;  # issue 128: the kept float32 state
            galewsky) if [ "$small" = 1 ]; then set -- --ne 2 --warmup 3 --graph-steps 2 --runs 2 --chain 2; else set -- --graph-steps 2000 --runs 5 --chain 50; fi
                run "precision_$item" "$limit" $p --scene galewsky $r --target-ms 0.05 "$@" ;;
            small) if [ "$small" = 1 ]; then set -- --ne 2 --warmup 3 --graph-steps 2 --runs 2 --chain 2; else set -- --ne 30 8 --graph-steps 2000 --runs 5 --chain 50; fi
                run "precision_$item" "$limit" $p --scene tc5_mountain $r --target-ms 0.05 "$@" ;;
            members) if [ "$small" = 1 ]; then set -- --ne 2 --members 2 --warmup 3 --graph-steps 2 --runs 2; else set -- --members "${MEMBERS:-32}" --warmup 20 --graph-steps 200 --runs 5; fi
                run "precision_$item" "$limit" $p --scene galewsky $r --chain "$@" ;;
            mpi) part_mpi "$limit" -k "card or gpu" ;;  # the CUDA tests alone (on a CPU: skipped)
            exchange) part_exchange "$limit" ;;
        esac
    done
    "$PY" benchmarks/gpu/gpu_session.py card --folder "$OUT" --results "$outer/card" >"$outer/card.md" 2>"$OUT/card_summary.txt" \
        || { cat "$OUT/card_summary.txt"; failed="$failed card"; }
    tar -C "$outer" -czf "$outer/card.tgz" card && rm -rf "$OUT"
    cat "$outer/card.md"
}

parts=("$@")
[ ${#parts[@]} -eq 0 ] && parts=(setup tests agreement throughput graphs tc5 iterations)
for part in "${parts[@]}"; do
    case $part in
        setup|tests_gpu|tests|agreement|throughput|graphs|bits|tc5|iterations|reads|study|study_ne60|study_fine|criterion_ne60|criterion_ne120|dinosaur|control|small|floor|kernels|ensemble|mpi|exchange|card) "part_$part" ;;
        *) echo "unknown part '$part' (setup tests_gpu tests agreement throughput graphs bits tc5 iterations reads study study_ne60 study_fine criterion_ne60 criterion_ne120 dinosaur control small floor kernels ensemble mpi exchange card)" >&2; exit 2 ;;
    esac
done
# every part ran (a failed one does not stop the rest: each is time-boxed on its own); the status says
# whether any failed or ran out of its time box, which a resumable study's may do
if [ -n "$failed" ]; then
    echo "== failed or stopped by its time box:$failed" | tee -a "$OUT/session.log"
    exit 1
fi
