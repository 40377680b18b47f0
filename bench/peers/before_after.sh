#!/usr/bin/env bash
# Two volcast builds side by side on this benchmark's scenes (not in CI): seconds per frame
# = (T(5 frames) - T(1 frame)) / 4 as in run_volcast.py, 2 threads, the builds interleaved.
#   bench/peers/before_after.sh BEFORE_BINARY AFTER_BINARY [DATA_DIR] [REPS]
# DATA_DIR is where run_all.sh wrote the volume (default /work/peers-data); REPS default 2.
# Prints "view mode before|after seconds" lines.
# Each run writes into an empty folder, and the order of the two builds alternates from one
# repetition to the next: with one shared folder and a fixed order, two copies of the same
# binary measured apart by more than the changes being measured.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
before=$1; after=$2; data=${3:-/work/peers-data}; reps=${4:-2}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
secs() {  # binary scene frames -> wall seconds
  local t0 t1
  rm -rf "$work/out"
  t0=$(date +%s.%N)
  "$1" render "$2" --out "$work/out" --quiet --no-view-reuse --threads 2 --frames "0..$3"
  t1=$(date +%s.%N)
  python3 -c "print($t1 - $t0)"
}
for r in $(seq "$reps"); do
  for view in ortho persp; do
    for mode in mip xray composite iso; do
      scene="$work/${view}_${mode}.toml"
      sed "s#/work/peers-data#$data#" "$here/scenes/${view}_${mode}.toml" > "$scene"
      order="before after"; [ $((r % 2)) = 0 ] && order="after before"
      for which in $order; do
        bin=$before; [ "$which" = after ] && bin=$after
        t1=$(secs "$bin" "$scene" 1); t5=$(secs "$bin" "$scene" 5)
        echo "$view $mode $which $(python3 -c "print(round(($t5 - $t1) / 4, 4))")"
      done
    done
  done
done
