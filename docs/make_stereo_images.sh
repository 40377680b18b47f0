#!/usr/bin/env bash
# Renders the stereo pictures of the README and of docs/stereo-and-batch.md from the example
# scenes, with the project's own binary. Run from anywhere: docs/make_stereo_images.sh [volcast]
set -euo pipefail
cd "$(dirname "$0")/.."
VOLCAST=${1:-target/release/volcast}
[ -x "$VOLCAST" ] || cargo build --release
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$VOLCAST" render --quiet --frames 0 --out "$tmp/anaglyph" scenes/stereo_engine.toml
"$VOLCAST" render --quiet --frames 0 --out "$tmp/sbs" scenes/stereo_engine_side_by_side.toml
# the whole turntable, small, for its GIF (the animation needs every frame)
"$VOLCAST" render --quiet --size 160x160 --out "$tmp/small" scenes/stereo_engine.toml
mkdir -p docs/images
cp "$tmp/anaglyph/engine_0000.png" docs/images/stereo_anaglyph.png
cp "$tmp/sbs/engine_0000.png" docs/images/stereo_side_by_side.png
cp "$tmp/small/engine.gif" docs/images/stereo_turntable.gif
echo "pictures written to docs/images/"
