#!/usr/bin/env bash
# Do two volcast builds write the same bytes? (not in CI) Renders, with each binary, frame 0 of
# every peer-benchmark scene on the float32 and uint8 volumes (bench/peers/scenes/, 512 x 512)
# and frames 0..2 of every example scene (scenes/, at 160 x 120), and compares every image.
#   bench/same_bytes.sh BEFORE_BINARY AFTER_BINARY [PEERS_DATA_DIR]   (default /work/peers-data)
# Prints each image that differs and a count; exits 1 if any differs or a render fails.
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
a=$1; b=$2; data=${3:-/work/peers-data}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
n=0; bad=0
render() {  # binary scene out [args]
  local bin=$1 scene=$2 out=$3; shift 3
  "$bin" render "$scene" --out "$out" -q "$@" >/dev/null 2>&1
}
compare() {  # dir-a dir-b
  while IFS= read -r img; do
    n=$((n + 1))
    cmp -s "$1/$img" "$2/$img" || { echo "differs: $img"; bad=$((bad + 1)); }
  done < <(cd "$1" && find . -name '*.png' -o -name '*.nrrd' | sort)
}
if [ -d "$data" ]; then
  for f in "$root"/bench/peers/scenes/*.toml; do
    s=$(basename "$f" .toml)
    for kind in f32 u8; do
      sed -e "s#/work/peers-data#$data#" -e "s#volume_f32.nrrd#volume_$kind.nrrd#" "$f" > "$work/$s.$kind.toml"
      [ "$kind" = u8 ] && sed -i 's/^window = \[0.0, 1.0\]/window = [0.0, 255.0]/' "$work/$s.$kind.toml"
      for x in a b; do
        eval bin=\$$x
        render "$bin" "$work/$s.$kind.toml" "$work/$x/$s.$kind" --frames 0..1 || { echo "render failed: $x $s $kind"; bad=$((bad + 1)); }
      done
      compare "$work/a/$s.$kind" "$work/b/$s.$kind"
    done
  done
else
  echo "no peer data in $data (bench/peers/run_all.sh makes it): peer scenes left out" >&2
fi
cd "$root"
for f in scenes/*.toml; do
  s=$(basename "$f" .toml)
  for x in a b; do
    eval bin=\$$x
    # a scene with fewer than three frames renders its first
    render "$bin" "$f" "$work/$x/ex_$s" --frames 0..2 --size 160x120 ||
      render "$bin" "$f" "$work/$x/ex_$s" --frames 0..1 --size 160x120 ||
      { echo "render failed: $x $s"; bad=$((bad + 1)); }
  done
  compare "$work/a/ex_$s" "$work/b/ex_$s"
done
echo "compared $n images, $bad differ or failed"
[ "$bad" -eq 0 ]
