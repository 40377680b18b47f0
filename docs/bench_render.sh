#!/usr/bin/env bash
# Times whole renders of example scenes (the real code path, from the command line)
# and prints a Markdown table of medians. Run from the project root after
# `cargo build --release`: docs/bench_render.sh [runs] [threads]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${1:-5}
THREADS=${2:-$(nproc)}
VOLCAST=target/release/volcast
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
median() { sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }
echo "| scene (4 frames, 512 x 512, $THREADS threads) | pass | seconds per frame | M samples/s |"
echo "|---|---|---|---|"
for s in mip_head xray_engine golden_engine composite_engine_bone golden_head; do
  secs=(); rates=()
  for _ in $(seq "$RUNS"); do
    rm -rf "$tmp/out"
    line=$("$VOLCAST" render "scenes/$s.toml" --frames 0..4 --size 512x512 --threads "$THREADS" --out "$tmp/out" 2>&1 | grep -E '^volcast: [0-9]+ files')
    # "volcast: 4 files (4 views, 1.2 MiB) in 1.23 s, 21.3 M samples/s -> ..."
    secs+=("$(sed -E 's/.* in ([0-9.]+) s,.*/\1/' <<<"$line")")
    rates+=("$(sed -E 's/.*, ([0-9.]+) M samples\/s.*/\1/' <<<"$line")")
  done
  passes=$(grep -c '^\[\[render\]\]' "scenes/$s.toml")
  sec=$(printf '%s\n' "${secs[@]}" | median)
  rate=$(printf '%s\n' "${rates[@]}" | median)
  per_frame=$(awk -v s="$sec" -v p="$passes" 'BEGIN {printf "%.3f", s / (4 * p)}')
  mode=$(grep -m1 -E '^mode' "scenes/$s.toml" | sed -E 's/mode = "(.*)"/\1/')
  echo "| \`scenes/$s.toml\` | $mode ($passes pass$([ "$passes" -gt 1 ] && echo es)) | $per_frame | $rate |"
done
