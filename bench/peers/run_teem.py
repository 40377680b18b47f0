#!/usr/bin/env python3
"""teem 1.12 (Debian teem-apps) on the peer benchmark, orthographic view only.

teem-mrender -m max (MIP) and -m sum (X-ray), teem-miter for composite and iso (a steep opacity
ramp at 0.5 with miter's Phong, whose defaults are ka 0.1, kd 0.6, ks 0.3, exponent 30, and a
light from the eye). hoover puts the volume in [-1, 1]^3 with cell centring (teem 1.12's
default when the NRRD names no centring): the cube of voxel faces [-0.5, 255.5] is [-1, 1], so
one voxel is 2/256 world units, the step is 0.5 voxel = 1/256 and the common image window is
exactly [-1, 1]; image pixels are cell-centred. (teem therefore samples the outer half voxel,
where the reference and volcast see nothing; the values there are below 0.006.) miter's
transfer functions are NRRDs over gage(scalar:v) written here; its output is RGBA, not
premultiplied. Timing: whole processes (teem has no render-only API from the command line;
reading the 64 MB volume is a few hundredths of a second of it).
Usage: run_teem.py --out DIR [--data DIR] [--modes ...]"""
import argparse
import math
import os
import subprocess
import time

import nrrd
import numpy as np

import common as C

VOX = 2.0 / C.N                         # world units per voxel
WIN = C.HALF * VOX                      # 1: half the image window
ISO_RAMP = 0.005


def camera_args(tool):
    # mrender takes its window from -fv alone (its -ur/-vr are ignored): half-height
    # tan(fv/2) * eye distance; it puts row 0 at the bottom (to_common flips it). miter takes
    # -ur/-vr, given here from top to bottom so that row 0 is the top.
    w = repr(WIN)
    window = (["-fv", repr(2 * math.degrees(math.atan(WIN / 5.0)))] if tool == "mrender"
              else ["-ur", f"-{w}", w, "-vr", w, f"-{w}"])
    return ["-fr", "0", "-5", "0", "-at", "0", "0", "0", "-up", "0", "0", "1", "-or",
            "-ar", "-dn", "-2", "-di", "0", "-df", "2"] + window + [
            "-is", str(C.IMG), str(C.IMG), "-k00", "tent", "-step", repr(C.STEP * VOX), "-nt", "2"]


def write_txf(path, mode):
    v = np.linspace(0.0, 1.0, 1001)
    if mode == "composite":   # grey = v, opacity per voxel length
        rgba = np.stack([v, v, v, C.opacity_per_voxel(v)])
    else:                     # white, opaque from 0.5 on
        a = np.clip((v - (C.ISO - ISO_RAMP)) / (2 * ISO_RAMP), 0.0, 1.0)
        rgba = np.stack([np.ones_like(v)] * 3 + [a])
    with open(path, "w") as f:
        f.write("NRRD0004\ntype: float\ndimension: 2\nsizes: 4 %d\n" % len(v)
                + 'labels: "RGBA" "gage(scalar:v)"\naxis mins: NaN 0\naxis maxs: NaN 1\n'
                + "centers: ??? node\nencoding: ascii\n\n")
        np.savetxt(f, rgba.T, fmt="%.7g")


def command(mode, vol, out, work):
    if mode in ("mip", "xray"):
        m = "max" if mode == "mip" else "sum"
        return (["teem-mrender", "-i", vol, "-k", "scalar", "-q", "v", "-m", m]
                + camera_args("mrender") + ["-o", out])
    txf = os.path.join(work, f"txf_{mode}.nrrd")
    write_txf(txf, mode)
    shading = ["-ss", "none", "-ads", "1", "0", "0"] if mode == "composite" else \
        ["-ads", str(C.PHONG["ka"]), str(C.PHONG["kd"]), str(C.PHONG["ks"]), "-sp", str(C.PHONG["exponent"])]
    return (["teem-miter", "-i", vol, "-txf", txf, "-ref", repr(VOX), "-n1", "0.99"]
            + shading + camera_args("miter") + ["-o", out])


def to_common(mode, path):
    img, _ = nrrd.read(path, index_order="C")
    img = np.asarray(img, dtype=np.float64)
    if mode == "mip":   # mrender: row 0 at the bottom
        return np.flipud(np.clip(np.nan_to_num(img, nan=0.0, neginf=0.0), 0.0, None))
    if mode == "xray":  # sum of samples 0.5 voxel apart
        return np.flipud(np.nan_to_num(img)) * C.STEP / C.XRAY_LENGTH
    if mode == "composite":
        return img[..., 0] * img[..., 3]                        # RGBA, not premultiplied
    return {"mask": img[..., 3] > 0.5, "shade": img[..., 0]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--out", required=True)
    ap.add_argument("--modes", default=",".join(C.MODES))
    a = ap.parse_args()
    work = os.path.join(a.out, "teem_work")
    os.makedirs(work, exist_ok=True)
    vol = C.volume_path(a.data, "f32")
    for mode in a.modes.split(","):
        out = os.path.join(work, f"{mode}.nrrd")
        cmd = command(mode, vol, out, work)
        start = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        secs = time.perf_counter() - start
        if r.returncode != 0:
            raise SystemExit(f"run_teem: {' '.join(cmd)} failed:\n{r.stderr}")
        C.save_result(a.out, "teem", mode, "ortho", to_common(mode, out))
        C.emit({"peer": "teem", "mode": mode, "view": "ortho", "seconds": secs})


if __name__ == "__main__":
    main()
