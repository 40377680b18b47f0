#!/usr/bin/env bash
# Renders the pictures of the README from the example scenes, with the project's own
# binary. Run from the project root: docs/make_images.sh [path/to/volcast]
set -euo pipefail
cd "$(dirname "$0")/.."
VOLCAST=${1:-target/release/volcast}
[ -x "$VOLCAST" ] || cargo build --release
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
render() { "$VOLCAST" render --quiet --frames 0 --size 256x256 --out "$tmp/$1" "scenes/$1.toml"; }
for s in xray_engine mip_head head_modes minip_ventricles depth_engine golden_engine golden_head golden_skull composite_engine_bone transfer_2d marschner_lobb colormap_engine preset_mr_head activation_overlay; do
  render "$s"
done
cp "$tmp/xray_engine/xray_0000.png"                docs/images/xray.png
cp "$tmp/xray_engine/integral_0000.png"            docs/images/xray_integral.png
cp "$tmp/mip_head/mip_0000.png"                    docs/images/mip.png
cp "$tmp/head_modes/lmip_0000.png"                 docs/images/lmip.png
cp "$tmp/minip_ventricles/minip_0000.png"          docs/images/minip.png
cp "$tmp/head_modes/average_0000.png"              docs/images/average.png
cp "$tmp/depth_engine/depth_0000.png"              docs/images/depth.png
cp "$tmp/golden_engine/gold_0000.png"              docs/images/surface.png
cp "$tmp/golden_head/surface_0000.png"             docs/images/surface_head.png
cp "$tmp/golden_skull/skull_0000.png"              docs/images/golden_skull.png
cp "$tmp/composite_engine_bone/bone_0000.png"      docs/images/composite.png
cp "$tmp/transfer_2d/composite_0000.png"           docs/images/composite_2d.png
cp "$tmp/marschner_lobb/trilinear_0000.png"        docs/images/ml_trilinear.png
cp "$tmp/marschner_lobb/cubic_0000.png"            docs/images/ml_cubic.png
cp "$tmp/colormap_engine/mip_hot_0000.png"         docs/images/colormap_hot.png
cp "$tmp/colormap_engine/xray_bone_0000.png"       docs/images/colormap_bone.png
cp "$tmp/colormap_engine/depth_viridis_0000.png"   docs/images/colormap_viridis.png
cp "$tmp/preset_mr_head/mr_default_0000.png"       docs/images/preset_mr_default.png
cp "$tmp/activation_overlay/overlay_0000.png"      docs/images/activation_overlay.png
# a NIfTI input (README "Input formats")
"$VOLCAST" render --quiet --frames 0 --out "$tmp/ct_head_nifti" scenes/ct_head_nifti.toml
cp "$tmp/ct_head_nifti/skin_0000.png"              docs/images/nifti_skin.png
cp "$tmp/ct_head_nifti/mip_0000.png"               docs/images/nifti_mip.png
# the histograms for transfer-function design (README "Histograms for transfer-function design")
"$VOLCAST" histogram scenes/transfer_2d.toml --out "$tmp/histogram_2d" > /dev/null
cp "$tmp/histogram_2d/histogram2d.png"             docs/images/histogram2d_engine.png
"$VOLCAST" histogram scenes/composite_engine_bone.toml --out "$tmp/histogram_bone" > /dev/null
cp "$tmp/histogram_bone/histogram.png"             docs/images/histogram_engine_bone.png
# the overlays at a larger size (frame 3)
"$VOLCAST" render --quiet --frames 3 --size 384x384 --out "$tmp/overlays" scenes/colormap_engine.toml
cp "$tmp/overlays/depth_viridis_0003.png"          docs/images/overlays.png
# the turntable page of the golden skull (all 36 frames), photographed in headless
# Chromium by the browser test's tooling (needs chromium and chromedriver)
"$VOLCAST" render --quiet --size 256x256 --viewer --out "$tmp/skull_viewer" scenes/golden_skull.toml
VOLCAST_VIEWER_PAGE="$tmp/skull_viewer/index.html" VOLCAST_VIEWER_PICTURE="$PWD/docs/images/viewer.png" \
  cargo test --quiet --test integration viewer_picture_for_the_readme -- --ignored
echo "pictures written to docs/images/"
