#!/usr/bin/env bash
# Large-volume check (not run in CI): makes a 2048 x 2048 x 1600 uint16 volume
# (12.5 GiB, a detached NRRD header + raw data in native little-endian order, so
# volcast memory-maps it), then measures wall time and peak memory of
#   info      the statistics pass over every voxel (streamed from the mapping)
#   render A  a 256 x 256 MIP, 1 frame, as a user would write it: the volume's window
#             from the data's range (statistics pass) and the grey window from the
#             preview renders
#   render B  the same MIP with both windows given (no statistics, no preview)
# Peak memory is sampled from /proc/PID/status every 0.1 s: RssAnon (memory the
# process allocated: what --max-memory is about) and RssFile (pages of the mapped
# file, which the kernel can drop at will), plus /proc/PID/smaps at the RssAnon peak
# (the largest anonymous regions) and GNU time's maximum RSS.
#
# Usage, from the project root:
#   bench/large_volume.sh                     # data in /work/large, target/release/volcast
#   LARGE_DIR=/elsewhere NZ=400 bench/large_volume.sh   # smaller volume (2048 x 2048 x 400)
#   VOLCAST=target/debug/volcast bench/large_volume.sh  # another build
# The data is generated once (kept for later runs; delete LARGE_DIR to start over)
# and never goes into the repository. Needs python3 with numpy for the generator.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
LARGE_DIR=${LARGE_DIR:-/work/large}
NX=${NX:-2048}
NY=${NY:-2048}
NZ=${NZ:-1600}
SIZE=${SIZE:-256x256}
THREADS=${THREADS:-$(nproc)}
VOLCAST=${VOLCAST:-target/release/volcast}
BYTES=$((NX * NY * NZ * 2))
RAW=$LARGE_DIR/volume_${NX}x${NY}x${NZ}.raw
NHDR=$LARGE_DIR/volume_${NX}x${NY}x${NZ}.nhdr

gib() { awk -v b="$1" 'BEGIN {printf "%.2f GiB", b / 2^30}'; }
mib_of_kib() { awk -v k="$1" 'BEGIN {printf "%.1f MiB", k / 1024}'; }

mkdir -p "$LARGE_DIR"
echo "== disk"
df -h "$LARGE_DIR"
if [ ! -f "$RAW" ] || [ "$(stat -c %s "$RAW")" -ne "$BYTES" ]; then
  free=$(df -B1 --output=avail "$LARGE_DIR" | tail -1)
  if [ "$free" -lt $((BYTES + (2 << 30))) ]; then
    echo "need $(gib $BYTES) + 2 GiB free in $LARGE_DIR, have $(gib "$free")" >&2
    exit 1
  fi
fi

if [ "$VOLCAST" = target/release/volcast ]; then
  echo "== build"
  cargo build --release --quiet
fi
VOLCAST=$(realpath "$VOLCAST")

if [ ! -f "$RAW" ] || [ "$(stat -c %s "$RAW")" -ne "$BYTES" ]; then
  echo "== generating $RAW ($(gib $BYTES)), slab by slab"
  python3 - "$RAW" "$NX" "$NY" "$NZ" <<'PY'
import sys, time
import numpy as np

path, nx, ny, nz = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
# A few Gaussian blobs (centre in [0, 1]^3, sigma, weight): separable, so each blob
# is one precomputed x-y plane times a z profile, and a slab costs a few multiply-adds.
blobs = [((0.35, 0.40, 0.45), 0.12, 1.0), ((0.65, 0.60, 0.55), 0.08, 0.8),
         ((0.50, 0.30, 0.70), 0.05, 0.6), ((0.45, 0.70, 0.30), 0.15, 0.4)]
x = np.linspace(0.0, 1.0, nx, dtype=np.float32)
y = np.linspace(0.0, 1.0, ny, dtype=np.float32)
z = np.linspace(0.0, 1.0, nz, dtype=np.float32)
planes, profiles = [], []
for (cx, cy, cz), s, w in blobs:
    gx = np.exp(-((x - cx) ** 2) / (2 * s * s))
    gy = np.exp(-((y - cy) ** 2) / (2 * s * s))
    planes.append(w * np.outer(gy, gx))            # (ny, nx), x fastest
    profiles.append(np.exp(-((z - cz) ** 2) / (2 * s * s)))
scale = 60000.0 / sum(w for _, _, w in blobs)
slab = 8
t0 = time.time()
with open(path + ".part", "wb") as f:
    for k0 in range(0, nz, slab):
        k1 = min(nz, k0 + slab)
        out = np.empty((k1 - k0, ny, nx), dtype="<u2")
        for k in range(k0, k1):
            acc = np.zeros((ny, nx), dtype=np.float32)
            for p, g in zip(planes, profiles):
                acc += g[k] * p
            out[k - k0] = np.rint(acc * scale).astype("<u2")
        f.write(out.tobytes())
        if k0 % 160 == 0:
            print(f"  slice {k0}/{nz}, {time.time() - t0:.0f} s", flush=True)
import os
os.replace(path + ".part", path)
print(f"  done in {time.time() - t0:.0f} s")
PY
fi

cat >"$NHDR" <<EOF
NRRD0004
content: bench/large_volume.sh blobs
type: uint16
dimension: 3
sizes: $NX $NY $NZ
spacings: 1 1 1
endian: little
encoding: raw
data file: $(basename "$RAW")
EOF

scene() { # scene NAME EXTRA_VOLUME_KEYS EXTRA_PASS_KEYS
  cat >"$LARGE_DIR/$1.toml" <<EOF
[volume]
path = "$(basename "$NHDR")"
$2
[camera]
azimuth = 30.0
elevation = 20.0

[image]
size = [256, 256]
out = "$LARGE_DIR/out/$1"

[[render]]
mode = "mip"
$3
EOF
}
scene large_mip_auto "" ""

# measure LABEL CMD...: runs CMD, samples its memory, prints a summary.
measure() {
  local label=$1
  shift
  local log=$LARGE_DIR/$label
  /usr/bin/time -v -o "$log.time" "$@" >"$log.out" 2>&1 &
  local tpid=$! pid="" t0 peak_anon=0 peak_file=0 hwm=0
  t0=$(date +%s.%N)
  while [ -z "$pid" ] && kill -0 "$tpid" 2>/dev/null; do
    pid=$(pgrep -P "$tpid" | head -1 || true)
    sleep 0.01
  done
  while [ -n "$pid" ] && [ -r "/proc/$pid/status" ]; do
    local st anon file h
    st=$(cat "/proc/$pid/status" 2>/dev/null) || break
    anon=$(awk '/^RssAnon:/ {print $2}' <<<"$st")
    file=$(awk '/^RssFile:/ {print $2}' <<<"$st")
    h=$(awk '/^VmHWM:/ {print $2}' <<<"$st")
    [ -n "$anon" ] || break
    if [ "$anon" -gt "$peak_anon" ]; then
      peak_anon=$anon
      cp "/proc/$pid/smaps" "$log.smaps" 2>/dev/null || true
      cp "/proc/$pid/smaps_rollup" "$log.rollup" 2>/dev/null || true
    fi
    [ "$file" -gt "$peak_file" ] && peak_file=$file
    [ "$h" -gt "$hwm" ] && hwm=$h
    sleep 0.1
  done
  local rc=0
  wait "$tpid" || rc=$?
  local wall
  wall=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN {printf "%.1f", b - a}')
  local maxrss
  maxrss=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$log.time")
  echo "== $label: exit $rc, wall $wall s"
  echo "   peak RssAnon $(mib_of_kib "$peak_anon"), peak RssFile $(mib_of_kib "$peak_file"), VmHWM $(mib_of_kib "$hwm"), GNU time max RSS $(mib_of_kib "$maxrss")"
  grep -E '^volcast: [0-9]+ files|^(type|range) ' "$log.out" | sed 's/^/   /' || true
  if [ "$rc" -ne 0 ]; then sed 's/^/   /' "$log.out"; fi
  if [ -f "$log.smaps" ]; then
    echo "   at the RssAnon peak, the largest anonymous regions (smaps):"
    awk '/^[0-9a-f]+-[0-9a-f]+ / {name = ($6 == "" ? "[anon mmap]" : $6); range = $1}
         /^Anonymous:/ && $2 > 0 {print $2, name, range}' "$log.smaps" |
      sort -rn | head -6 | awk '{printf "     %10.1f MiB  %s %s\n", $1 / 1024, $2, $3}'
    awk '/^Anonymous:/ {a += $2} END {printf "     total anonymous %.1f MiB\n", a / 1024}' "$log.smaps"
    awk -v f="$(basename "$RAW")" '/^[0-9a-f]+-[0-9a-f]+ / {m = index($0, f) > 0}
         m && /^Rss:/ {r += $2} END {printf "     resident pages of the mapped volume %.1f MiB\n", r / 1024}' "$log.smaps"
  fi
  rm -f "$log.smaps"
}

echo "== volcast $("$VOLCAST" --version 2>/dev/null || echo "(no --version)"), $THREADS threads, volume $NX x $NY x $NZ uint16 = $(gib $BYTES)"
grep -E '^(MemTotal|MemAvailable|Cached)' /proc/meminfo
"$VOLCAST" check "$LARGE_DIR/large_mip_auto.toml" --size "$SIZE" --threads "$THREADS" | sed 's/^/   /'
measure info "$VOLCAST" info "$NHDR"
# render B: the volume window that render A computes (the data's range, from info)
range=$(awk '/^range / {print $2 ", " $4}' "$LARGE_DIR/info.out")
scene large_mip_windows "window = [${range:-0, 65535}]" "window = [0.0, 1.0]"
measure render_A "$VOLCAST" render "$LARGE_DIR/large_mip_auto.toml" --size "$SIZE" --threads "$THREADS"
measure render_B "$VOLCAST" render "$LARGE_DIR/large_mip_windows.toml" --size "$SIZE" --threads "$THREADS"
echo "logs and images in $LARGE_DIR"
