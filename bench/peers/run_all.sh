#!/usr/bin/env bash
# The whole peer benchmark in one command (bench/peers/README.md):
#   bench/peers/run_all.sh [RESULTS_DIR] [DATA_DIR]
# Installs what is missing (Debian packages, PyPI packages: needs the package registries),
# writes the volume into DATA_DIR (default /work/peers-data, outside the repository), computes
# or reuses the reference images, then runs volcast and every peer interleaved, REPS times
# (default 5), and writes results.md, results.csv and speed_vs_error.png into RESULTS_DIR
# (default /work/peers-results). VOLCAST names the binary (default
# /work/main/target/release/volcast).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
results=${1:-/work/peers-results}
data=${2:-/work/peers-data}
export VOLCAST=${VOLCAST:-/work/main/target/release/volcast}
reps=${REPS:-5}
export PYTHONDONTWRITEBYTECODE=1   # no __pycache__ in the repository

[ -x "$VOLCAST" ] || { echo "run_all: no volcast binary at $VOLCAST (build it, or set VOLCAST)" >&2; exit 1; }

missing=()
command -v teem-mrender >/dev/null || missing+=(teem-apps)
[ -f /usr/include/volpack.h ] || missing+=(libvolpack1-dev)
command -v gcc >/dev/null || missing+=(gcc)
for p in libegl-mesa0 libosmesa6 libgl1-mesa-dri; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "run_all: installing ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi
if ! python3 -c "import numpy, nrrd, PIL, matplotlib, vtk; assert vtk.vtkVersion.GetVTKVersion() == '9.7.2'" 2>/dev/null; then
  echo "run_all: installing vtk==9.7.2 numpy pynrrd pillow matplotlib from PyPI"
  python3 -m pip install -q vtk==9.7.2 numpy pynrrd pillow matplotlib
fi

[ -f "$data/volume_f32.nrrd" ] && [ -f "$data/volume_u8.nrrd" ] || python3 "$here/make_volume.py" "$data"
python3 "$here/reference.py" --data "$data" --out "$data/reference" --views ortho,persp --kinds f32
python3 "$here/reference.py" --data "$data" --out "$data/reference" --views ortho --kinds u8
mkdir -p "$results"
python3 "$here/bench.py" --data "$data" --results "$results" --reps "$reps"
echo "run_all: results in $results (results.md, results.csv, speed_vs_error.png, images/)"
