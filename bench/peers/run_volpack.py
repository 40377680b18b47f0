#!/usr/bin/env python3
"""VolPack 1.0b3 (Debian libvolpack1-dev) on the peer benchmark: composite, orthographic view,
the uint8 volume. Builds volpack_render.c (ours, beside this script) with gcc into
OUT/volpack_work, runs it, stores the image in the common form and prints RESULT lines:
'volpack' = render of the pre-classified (run-length encoded) volume, median of --renders;
'volpack-raw' = one render straight from the raw voxels (classification on the fly).
VolPack is single-threaded, shear-warp (one resampled slice per voxel: no step size), 8-bit.
Its image sits 0.25 voxel (x) and 0.75 voxel (z) away from the common world rectangle
(measured: README "VolPack"), so the model is translated by that much to cover the same one.
Usage: run_volpack.py --out DIR [--data DIR] [--renders 5]"""
import argparse
import os
import subprocess

import numpy as np
from PIL import Image

import common as C

HERE = os.path.dirname(os.path.abspath(__file__))
MIN_VOXEL_OPACITY = 0.002      # VolPack's default drops voxels with opacity < 0.05 entirely
SHIFT_X, SHIFT_Z = 0.25, 0.75  # voxels: moves VolPack's image onto the common rectangle


def build(work):
    exe = os.path.join(work, "volpack_render")
    src = os.path.join(HERE, "volpack_render.c")
    if not os.path.exists(exe) or os.path.getmtime(exe) < os.path.getmtime(src):
        os.makedirs(work, exist_ok=True)
        subprocess.run(["gcc", "-O2", "-Wall", "-o", exe, src, "-lvolpack", "-lm"], check=True)
    return exe


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--out", required=True)
    ap.add_argument("--renders", type=int, default=5)
    a = ap.parse_args()
    work = os.path.join(a.out, "volpack_work")
    exe = build(work)
    pgm = os.path.join(work, "composite.pgm")
    r = subprocess.run([exe, C.volume_path(a.data, "u8"), pgm, str(a.renders),
                        str(MIN_VOXEL_OPACITY), str(SHIFT_X), str(SHIFT_Z)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"run_volpack: {exe} failed:\n{r.stderr}")
    t = {k: float(v) for k, v in (line.split() for line in r.stdout.split("\n") if line)}
    img = np.asarray(Image.open(pgm), dtype=np.float64) / 255.0   # premultiplied grey, row 0 top
    C.save_result(a.out, "volpack", "composite", "ortho", img)
    C.save_result(a.out, "volpack-raw", "composite", "ortho", img)
    C.emit({"peer": "volpack", "mode": "composite", "view": "ortho", "seconds": t["render"],
            "classify": t["classify"]})
    C.emit({"peer": "volpack-raw", "mode": "composite", "view": "ortho", "seconds": t["render_raw"]})


if __name__ == "__main__":
    main()
