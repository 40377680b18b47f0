#!/usr/bin/env python3
"""Where the peer benchmark's composite spends its samples and what a coarser step costs
(issue 7; the numbers in the README's "Where the time goes now"). Not part of CI.

1. Samples (numpy, no volcast code): the orthographic composite's midpoint samples (rays along
   +y through the pixel centres, samples at 0.25 + 0.5 k voxel), early termination at 0.99,
   counted per frame: those in macrocells a skipping composite cannot pass over (the cell's
   maximum over its voxels and one voxel of margin reaches the opacity ramp's start, 0.1, less
   two 8-bit steps of slack), and of those, the ones with an opacity. For macrocells of 8^3
   voxels (volcast's) and 4^3.
2. Steps: volcast's composite at steps 0.5, 1, 1.5 and 2 voxels in both views: RMSE against
   the reference (common.errors) and seconds per frame, (T(5 frames) - T(1 frame)) / 4 with
   --no-view-reuse, 2 threads, as run_volcast.py times it.
3. The walk alone: the orthographic composite with opacity only at the value 1.0, so that
   every macrocell is walked and almost none sampled: seconds per frame.

Usage: composite_study.py [--volcast BIN] [--data DIR] [--out DIR] [--reps N]"""
import argparse
import os

import numpy as np

import common as C
import run_volcast as R


def count_samples(data_dir):
    v = C.load_volume(data_dir, "f32")   # indexed [z, y, x]; the rays run along axis 1

    def up(a, axis):
        # the trilinear field at 0.25, 0.75, 1.25, ... along one axis (510 positions)
        a0 = np.take(a, range(0, C.N - 1), axis=axis)
        a1 = np.take(a, range(1, C.N), axis=axis)
        out = np.stack([0.75 * a0 + 0.25 * a1, 0.25 * a0 + 0.75 * a1], axis=axis + 1)
        shape = list(a.shape)
        shape[axis] = 2 * (C.N - 1)
        return out.reshape(shape)

    u = up(up(up(v, 0), 1), 2)
    a = np.where(u > 0.1, 0.2 * (u - 0.1) / 0.9, 0.0).astype(np.float32)
    a = 1 - (1 - a) ** 0.5                      # opacity per half-voxel step
    reached = (1 - np.cumprod(1 - a, axis=1)) >= 0.99
    before = np.cumsum(reached, axis=1) - reached > 0
    alive = ~before                             # samples up to the one that terminates
    pos = 0.25 + 0.5 * np.arange(2 * (C.N - 1))
    for m in (8, 4):
        cells = (C.N - 1 + m - 1) // m

        def cell_max(x, axis):
            parts = []
            for c in range(cells):
                lo, hi = max(c * m - 1, 0), min((c + 1) * m + 1, C.N - 1)
                parts.append(np.take(x, range(lo, hi + 1), axis=axis).max(axis=axis))
            return np.stack(parts, axis=axis)

        opaque = cell_max(cell_max(cell_max(v, 0), 1), 2) >= 0.1 - 2 / 255
        cell = np.minimum((pos // m).astype(int), cells - 1)
        taken = opaque[cell][:, cell][:, :, cell] & alive
        useful = taken & (a > 0)
        print(f"macrocells of {m}^3: {taken.sum() / 1e6:.1f} M samples taken per frame, "
              f"{useful.sum() / 1e6:.1f} M ({useful.sum() / taken.sum():.0%}) with an opacity")


def scene(view, data, work, step, alpha=None):
    R.VARIANTS["study"] = (("composite",), f"step = {step}", None)
    path = R.scene_copy(view, "composite", data, work, "study")
    if alpha is not None:
        text = open(path).read()
        start = text.index("\nalpha = ")
        end = text.index("\n", start + 1)
        text = text[:start] + f"\nalpha = {alpha}" + text[end:]
        with open(path, "w") as f:
            f.write(text)
    return path


def per_frame(volcast, path, out, reps):
    base = [volcast, "render", path, "--out", out, "--quiet", "--no-view-reuse", "--threads", "2"]
    times = []
    for _ in range(reps):
        t1 = R.timed(base + ["--frames", "0..1"])
        t5 = R.timed(base + ["--frames", "0..5"])
        times.append((t5 - t1) / 4)
    return float(np.median(times))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--volcast", default=os.environ.get("VOLCAST", "/work/main/target/release/volcast"))
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--out", default="/tmp/composite_study")
    ap.add_argument("--reps", type=int, default=3)
    a = ap.parse_args()
    count_samples(a.data)
    for view in C.VIEWS:
        ref = np.load(os.path.join(a.data, "reference", f"ref_f32_{view}_composite.npy"))
        for step in ("0.5", "1.0", "1.5", "2.0"):
            path = scene(view, a.data, a.out, step)
            out = os.path.join(a.out, f"{view}_{step}")
            seconds = per_frame(a.volcast, path, out, a.reps)
            img = R.to_common("composite", os.path.join(out, "img_0000.nrrd"))
            rmse = C.errors("composite", img, ref)["rmse"]
            print(f"{view} step {step}: RMSE {rmse:.3f}, {seconds:.3f} s per frame")
    path = scene("ortho", a.data, a.out, "0.5", alpha="[[0.0, 0.0], [0.999, 0.0], [1.0, 0.2]]")
    seconds = per_frame(a.volcast, path, os.path.join(a.out, "walk"), a.reps)
    print(f"ortho, opacity only at 1.0 (the walk alone): {seconds:.3f} s per frame")


if __name__ == "__main__":
    main()
