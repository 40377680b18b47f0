#!/usr/bin/env python3
"""The composite's error against the reference over its step and its early stop: volcast renders the peer benchmark's composite scene with
`step` and `early_stop` changed, one frame, and each image is compared with the brute-force
reference (common.errors: RMSE in grey levels of 255). Shows that the scenes' stop at 0.99 is
most of the default's error, and that step 1 with a stop at 0.995 is closer to the reference.
With --reps N, also the CPU time per frame with one thread ((T(5 frames) - T(1 frame)) / 4,
median of N). Not part of CI.

Usage: stop_study.py [--volcast BIN] [--data DIR] [--views ortho,persp] [--kind f32|u8]
                     [--settings 0.5:0.99,0.5:1.0,1:0.99,1:0.995,1:1.0] [--reps N]"""
import argparse
import os
import resource
import shutil
import statistics
import subprocess
import tempfile

import common as C
import run_volcast as R


def cpu_per_frame(base, out, reps):
    """CPU seconds per frame, one thread: (T(5 frames) - T(1 frame)) / 4, median of `reps`."""
    def cpu(frames):
        shutil.rmtree(out, ignore_errors=True)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run(base + ["--frames", f"0..{frames}"], check=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return statistics.median((cpu(5) - cpu(1)) / 4 for _ in range(reps))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--volcast", default=os.environ.get("VOLCAST", "/work/main/target/release/volcast"))
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--views", default="ortho,persp")
    ap.add_argument("--kind", choices=("f32", "u8"), default="f32")
    ap.add_argument("--settings", default="0.25:1.0,0.5:0.99,0.5:1.0,1:0.99,1:0.995,1:1.0",
                    help="step:early_stop pairs")
    ap.add_argument("--reps", type=int, default=0, help="time each setting, median of N")
    a = ap.parse_args()
    refs = os.path.join(a.data, "reference")
    print("| view | step | early_stop | RMSE | max | CPU s per frame, 1 thread |")
    print("| --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as work:
        for view in a.views.split(","):
            ref = C.load_result(refs, f"ref_{a.kind}", "composite", view)
            for setting in a.settings.split(","):
                step, stop = setting.split(":")
                R.VARIANTS["stop_study"] = (("composite",), f"step = {step}", float(stop))
                scene = R.scene_copy(view, "composite", a.data, work, "stop_study", a.kind)
                out = os.path.join(work, f"out_{view}_{step}_{stop}")
                subprocess.run([a.volcast, "render", scene, "--out", out, "--quiet",
                                "--frames", "0..1"], check=True)
                got = R.to_common("composite", os.path.join(out, "img_0000.nrrd"))
                e = C.errors("composite", got, ref)
                seconds = "-"
                if a.reps > 0:
                    base = [a.volcast, "render", scene, "--out", out, "--quiet",
                            "--no-view-reuse", "--threads", "1"]
                    seconds = f"{cpu_per_frame(base, out, a.reps):.4f}"
                print(f"| {view} | {step} | {stop} | {e['rmse']:.3f} | {e['max']:.2f} | {seconds} |")


if __name__ == "__main__":
    main()
