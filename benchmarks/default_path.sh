#!/bin/bash
# Whole-process wall time, CPU time and peak RSS of a default run (TC5, the scene's stepper, one
# thread, CPU) at ne30 and ne120: an earlier tree against this one, interleaved, each warmed once
# first (kernels compiled). For a change that joins the default path. BASE_ARGS: more `run`
# arguments for the base runs alone (a scene default against its old value, one tree for both).
#   git worktree add /tmp/base <rev> && bash benchmarks/default_path.sh /tmp/base
#   BASE_ARGS="-s hyperviscosity.every=1" bash benchmarks/default_path.sh . .
set -euo pipefail
BASE=${1:?usage: default_path.sh BASE_TREE [HEAD_TREE]}
HEAD=${2:-$(cd "$(dirname "$0")/.." && pwd)}
for tree in "$BASE" "$HEAD"; do  # PYTHONPATH skips a tree that is not there: both would be the installed one
  [ -d "$tree/swe_sphere" ] || { echo "default_path.sh: error: $tree holds no swe_sphere tree" >&2; exit 2; }
done
BASE=$(cd "$BASE" && pwd); HEAD=$(cd "$HEAD" && pwd)  # the runs start in folders of their own
BASE_ARGS=${BASE_ARGS:-}
run() { # tree ne days tag [more run arguments]
  local dir; dir=$(mktemp -d); cd "$dir"
  SWE_SPHERE_THREADS=1 PYTHONPATH=$1 /usr/bin/time -f "$4 ne$2 wall %e s cpu %U+%S s maxrss %M KiB" \
    python -c "import sys; from swe_sphere.cli import main; sys.exit(main(['run','tc5_mountain','--ne','$2','--days','$3','--no-progress','--device','cpu','--output','o.nc',*sys.argv[1:]]))" "${@:5}" >/dev/null 2>err.txt
  tail -1 err.txt; cd - >/dev/null; rm -rf "$dir"
}
uptime
for ne_days in "30 0.25" "120 0.01"; do
  set -- $ne_days
  # shellcheck disable=SC2086  # BASE_ARGS: words
  run "$BASE" "$1" "$2" warm $BASE_ARGS >/dev/null; run "$HEAD" "$1" "$2" warm >/dev/null
  for _ in 1 2; do run "$BASE" "$1" "$2" base $BASE_ARGS; run "$HEAD" "$1" "$2" head; done
done
uptime
