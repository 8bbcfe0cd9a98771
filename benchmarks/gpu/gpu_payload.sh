#!/usr/bin/env bash
# The packages the GPU machine lacks (Warp, netCDF4, cftime, ducc0, pyamg, mpich and mpi4py, and the peer Dinosaur's;
# benchmarks/gpu/GPU.md), as
# three pieces that each fit the device tool's 64 MiB a call beside the checkout: a Warp wheel
# alone is 149 MB (1.19.0), the four unpacked without Warp's tests and examples and
# compressed with xz 116 MB. Run here, from the repository root (≈ 3 min on 2 cores):
#
#   bash benchmarks/gpu/gpu_payload.sh            # writes .gpu1/ .gpu2/ .gpu3/ (git-ignored through .git/info/exclude)
#
# then, on a warm machine, one call a piece, the first two copying theirs to ~/stage
# (`run` with carry [".gpu1"]: `mkdir -p ~/stage && cp .gpu1/* ~/stage/`), the third
# unpacking them and going on in the same call:
#
#   cp .gpu3/* ~/stage/ && cat ~/stage/p.* | xz -dc | tar -C ~ -xf - &&
#   export PYTHONPATH=~/site PYTHON=python3 && bash benchmarks/gpu/gpu_session.sh setup tests_gpu bits …
#
# The machine is given back 30 s after a call: make the three calls back to back.
set -eu
cd "$(dirname "$0")/../.."
PYV=${PYV:-3.12}  # the GPU machine's Python (its image, 2026-11)
# the peer Dinosaur (benchmarks/peers/peer_dinosaur.py --device cuda) and what it imports that the image
# lacks (it has JAX 0.11 with its CUDA plugin, xarray, pandas, scipy, toolz, fsspec, cloudpickle):
# pure Python, 3 MB; the versions measured on the CPU (peer_dinosaur.py's venv)
PEER="dinosaur==1.5.1 pint==0.25.3 flexcache==0.3 flexparser==0.4 platformdirs==4.14.8 tree-math==0.2.1
      dask==2026.8.0 partd==1.4.2 locket==1.0.0"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
ver() { python -c "import importlib.metadata as m; print(m.version('$1'))"; }
python -m pip download -q --no-deps --only-binary=:all: --python-version "$PYV" --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 --platform manylinux1_x86_64 -d "$work/whl" \
    "warp-lang==$(ver warp-lang)" "netCDF4==$(ver netCDF4)" "cftime==$(ver cftime)" "ducc0==$(ver ducc0)" "pyamg==$(ver pyamg)" \
    "mpich==$(ver mpich)" "mpi4py==$(ver mpi4py)" $PEER
mkdir -p "$work/site"
for w in "$work"/whl/*.whl; do python -m zipfile -e "$w" "$work/site"; done
rm -rf "$work/site/warp/tests" "$work/site/warp/examples"
tar -C "$work" -cf - site | xz -T0 -9 >"$work/payload.tar.xz"
for d in .gpu1 .gpu2 .gpu3; do
    rm -rf "$d" && mkdir "$d"
    grep -qx "/$d/" .git/info/exclude 2>/dev/null || echo "/$d/" >>.git/info/exclude
done
split -n 3 -d "$work/payload.tar.xz" "$work/p."
mv "$work/p.00" .gpu1/ && mv "$work/p.01" .gpu2/ && mv "$work/p.02" .gpu3/
ls -l .gpu1 .gpu2 .gpu3
