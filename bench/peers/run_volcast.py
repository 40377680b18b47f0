#!/usr/bin/env python3
"""Runs volcast on the peer-benchmark scenes (bench/peers/scenes/{view}_{mode}.toml) and times it
as whole processes: seconds per frame = (T(--frames 0..5) - T(--frames 0..1)) / 4, with
--no-view-reuse (the five frames are the same view, which volcast would otherwise render once).
Stores frame 0 in the common form (common.py) and prints one RESULT line per case.
Usage: run_volcast.py --out DIR [--volcast BIN] [--data DIR] [--modes ...] [--views ...] [--kind u8]"""
import argparse
import os
import subprocess
import time

import numpy as np
import nrrd

import common as C

HERE = os.path.dirname(os.path.abspath(__file__))


# Opt-in settings that change the sample lattice, measured beside the default (issue 7:
# "a traversal that changes the sample lattice is an opt-in setting whose error ... shows"):
# name -> (modes, replacement for the pass's `step = 0.5` line, early_stop or None for the
# scene's 0.99). The composite's error at the default step is almost all the early stop at 0.99
# (0.03 grey levels without it, orthographic), so a coarser step with a later stop has a lower
# error than the default: step 1 with early_stop 0.995 has 0.19 (ortho) and 0.15 (persp)
# against the default's 0.31 and 0.25.
VARIANTS = {
    "volcast": (C.MODES, "step = 0.5", None),
    "volcast-step1": (("composite",), "step = 1.0", None),
    "volcast-step1-e995": (("composite",), "step = 1.0", 0.995),
    "volcast-pre2": (("composite",), "step = 2.0\npreintegrated = true", None),
}


def scene_copy(view, mode, data_dir, work, variant="volcast", kind="f32"):
    """The scene with its volume path pointing into data_dir, and the variant's step and early
    stop; for kind 'u8', the uint8 volume through the window [0, 255] (the same normalised
    values)."""
    src = open(os.path.join(HERE, "scenes", f"{view}_{mode}.toml")).read()
    _, step, early_stop = VARIANTS[variant]
    src = src.replace("\nstep = 0.5\n", "\n" + step + "\n")
    if early_stop is not None:
        assert "\nearly_stop = 0.99\n" in src
        src = src.replace("\nearly_stop = 0.99\n", f"\nearly_stop = {early_stop}\n")
    if kind == "u8":
        assert "volume_f32.nrrd" in src and "\nwindow = [0.0, 1.0]\n" in src
        src = src.replace("volume_f32.nrrd", "volume_u8.nrrd")
        src = src.replace("\nwindow = [0.0, 1.0]\n", "\nwindow = [0.0, 255.0]\n")
    path = os.path.join(work, f"{view}_{mode}_{variant}.toml")
    os.makedirs(work, exist_ok=True)
    with open(path, "w") as f:
        f.write(src.replace("/work/peers-data", os.path.abspath(data_dir)))
    return path


def to_common(mode, path):
    img, _ = nrrd.read(path, index_order="C")   # (H, W) or (H, W, 4), row 0 at the top
    img = np.asarray(img, dtype=np.float64)
    if mode == "mip":
        return np.nan_to_num(img, nan=0.0)
    if mode == "xray":
        return img / C.XRAY_LENGTH
    if mode == "composite":
        return img[..., 0] * img[..., 3]          # non-premultiplied RGBA -> grey over black
    return {"mask": img[..., 3] > 0.5, "shade": img[..., 0]}


def timed(cmd):
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--volcast", default=os.environ.get("VOLCAST", "/work/main/target/release/volcast"))
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--out", required=True, help="folder for images and scratch files")
    ap.add_argument("--modes", default=",".join(C.MODES))
    ap.add_argument("--views", default=",".join(C.VIEWS))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-timing", action="store_true", help="render frame 0 only")
    ap.add_argument("--kind", choices=("f32", "u8"), default="f32",
                    help="the volume read: float32 (the benchmark's) or uint8 (the issue's)")
    a = ap.parse_args()
    work = os.path.join(a.out, "volcast_work")
    for view in a.views.split(","):
        for mode in a.modes.split(","):
            for variant, (modes, _, _) in VARIANTS.items():
                if mode not in modes:
                    continue
                scene = scene_copy(view, mode, a.data, work, variant, a.kind)
                out = os.path.join(work, f"{view}_{mode}_{variant}")
                base = [a.volcast, "render", scene, "--out", out, "--quiet", "--no-view-reuse",
                        "--threads", str(a.threads)]
                t1 = timed(base + ["--frames", "0..1"])
                C.save_result(a.out, variant, mode, view,
                              to_common(mode, os.path.join(out, "img_0000.nrrd")))
                if a.no_timing:
                    continue
                t5 = timed(base + ["--frames", "0..5"])
                C.emit({"peer": variant, "mode": mode, "view": view, "seconds": (t5 - t1) / 4,
                        "process_1_frame": t1, "process_5_frames": t5})


if __name__ == "__main__":
    main()
