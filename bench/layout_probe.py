#!/usr/bin/env python3
"""Would a bricked or Morton-ordered volume layout win (issue 7)? CPU time per sample taken,
one thread, for MIP and composite frames of float32 blobs (`synthetic = "blobs"`) at 256^3
(64 MiB) and 64^3 (1 MiB, held in L2), with rays along +y and oblique (azimuth 20, elevation
15); and, given the peer benchmark's data, its volume with rays along x, y, z and oblique. A
sample that costs the same when the whole volume is in cache gains nothing from a layout.
Orthographic, 512 x 512, step 0.5, as the peer scenes. ns per sample = CPU seconds per frame
((T(5 frames) - T(1 frame)) / 4, median of REPS) / samples a frame takes (the manifest of a
one-frame render). Not part of CI.

Usage: python3 bench/layout_probe.py [--volcast BIN] [--reps 5] [--peer-data /work/peers-data]
  --keep DIR keeps the scenes, e.g. for instructions per frame at 256 x 256 (the AVX2 path):
    sed 's/^size = \[512, 512\]/size = [256, 256]/' DIR/SCENE.toml > small.toml
    valgrind --tool=cachegrind --cache-sim=yes --cachegrind-out-file=cg.out \
      BIN render small.toml --out o --quiet --no-view-reuse --threads 1 --frames 0..2
  (and --frames 0..1: the difference of the two is one frame; cg_annotate cg.out per function)"""
import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import tempfile

VIEWS = {"y": (0, 0), "oblique": (20, 15), "x": (90, 0), "z": (0, 90)}
ZOOM = 1.7252849841018112   # the peer scenes': the image spans the volume's 256 voxels
PASSES = {
    "mip": 'mode = "mip"\nwindow = [0.0, 1.0]\n',
    "composite": 'mode = "composite"\ntransfer = "bench"\nreference_step = 1.0\nearly_stop = 0.99\n',
}
TRANSFER = ('[transfer.bench]\ninterpolation = "linear"\n'
            'color = [[0.0, [0.0, 0.0, 0.0]], [1.0, [1.0, 1.0, 1.0]]]\n'
            'alpha = [[0.0, 0.0], [0.1, 0.0], [1.0, 0.2]]\n')


def scene(volume, view, mode):
    az, el = VIEWS[view]
    return (f"[volume]\n{volume}\n[camera]\nprojection = \"orthographic\"\nazimuth = {az}\n"
            f"elevation = {el}\nzoom = {ZOOM}\n[orbit]\nframes = 5\ndegrees = 0.0\n"
            f"[image]\nsize = [512, 512]\nformat = \"nrrd\"\n{TRANSFER}[[render]]\n"
            f"{PASSES[mode]}step = 0.5\ninterpolation = \"trilinear\"\n")


def cpu_seconds(cmd):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--volcast", default=os.environ.get("VOLCAST", "target/release/volcast"))
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--peer-data", default="/work/peers-data")
    ap.add_argument("--keep", help="folder to keep the scenes in")
    a = ap.parse_args()
    cases = [(f"blobs {n}^3 float32",
              f'synthetic = "blobs"\nsizes = [{n}, {n}, {n}]\ntype = "float32"', view)
             for n in (256, 64) for view in ("y", "oblique")]
    peer = os.path.join(a.peer_data, "volume_f32.nrrd")
    if os.path.exists(peer):
        cases += [("peer volume", f'path = "{os.path.abspath(peer)}"\nwindow = [0.0, 1.0]', view)
                  for view in ("x", "y", "z", "oblique")]
    else:
        print(f"(no {peer}: the peer volume's axes are left out)")
    work = a.keep or tempfile.mkdtemp()
    os.makedirs(work, exist_ok=True)
    print("| volume | rays | mode | samples a frame | CPU s per frame | ns per sample |")
    print("| --- | --- | --- | --- | --- | --- |")
    try:
        for k, (name, volume, view) in enumerate(cases):
            for mode in PASSES:
                path = os.path.join(work, f"case{k}_{view}_{mode}.toml")
                with open(path, "w") as f:
                    f.write(scene(volume, view, mode))
                out = os.path.join(work, "out")
                base = [a.volcast, "render", path, "--out", out, "--quiet", "--no-view-reuse",
                        "--threads", "1"]
                shutil.rmtree(out, ignore_errors=True)
                subprocess.run(base + ["--frames", "0..1"], check=True, stdout=subprocess.DEVNULL)
                samples = json.load(open(os.path.join(out, "manifest.json")))["totals"]["samples"]
                times = []
                for _ in range(a.reps):
                    shutil.rmtree(out, ignore_errors=True)
                    t5 = cpu_seconds(base + ["--frames", "0..5"])
                    shutil.rmtree(out, ignore_errors=True)
                    t1 = cpu_seconds(base + ["--frames", "0..1"])
                    times.append((t5 - t1) / 4)
                t = statistics.median(times)
                print(f"| {name} | {view} | {mode} | {samples / 1e6:.2f} M | {t:.4f} | "
                      f"{t / samples * 1e9:.2f} |")
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
