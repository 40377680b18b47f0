#!/usr/bin/env bash
# Instructions per frame of the peer scenes, counted by valgrind (not in CI): a measure the
# machine's noise does not move. Each scene is rendered at 256 x 256 with one thread, with
# --frames 0..1 and 0..2; the difference of the two `I refs` is one frame, the first count
# less that is the set-up. valgrind runs the AVX2 path (it has no AVX-512).
#   bench/peers/instructions.sh BINARY [DATA_DIR] [SCENE ...]   (scenes default:
#   ortho_composite ortho_xray persp_mip; DATA_DIR default /work/peers-data)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
bin=$1; data=${2:-/work/peers-data}; shift $(( $# > 1 ? 2 : 1 ))
scenes=("$@"); [ ${#scenes[@]} -gt 0 ] || scenes=(ortho_composite ortho_xray persp_mip)
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
refs() {  # scene frames -> I refs
  valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null \
    "$bin" render "$1" --out "$work/out" --quiet --no-view-reuse --threads 1 --frames "0..$2" 2>&1 |
    sed -n 's/.*I *refs: *//p' | tr -d ,
}
for s in "${scenes[@]}"; do
  sed -e "s#/work/peers-data#$data#" -e 's/^size = \[512, 512\]/size = [256, 256]/' \
    "$here/scenes/$s.toml" > "$work/$s.toml"
  one=$(refs "$work/$s.toml" 1); two=$(refs "$work/$s.toml" 2)
  echo "$s frame $((two - one)) setup $((one - (two - one)))"
done
