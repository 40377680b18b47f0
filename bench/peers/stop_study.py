#!/usr/bin/env python3
"""The composite's error against the reference over its step and its early stop (issue 7, the
fourteenth round in README.md): volcast renders the peer benchmark's composite scene with
`step` and `early_stop` changed, one frame, and each image is compared with the brute-force
reference (common.errors: RMSE in grey levels of 255). Shows that the scenes' stop at 0.99 is
most of the default's error, and that step 1 with a stop at 0.995 is closer to the reference.
Not part of CI.

Usage: stop_study.py [--volcast BIN] [--data DIR] [--views ortho,persp] [--kind f32|u8]
                     [--settings 0.5:0.99,0.5:1.0,1:0.99,1:0.995,1:1.0]"""
import argparse
import os
import subprocess
import tempfile

import common as C
import run_volcast as R


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--volcast", default=os.environ.get("VOLCAST", "/work/main/target/release/volcast"))
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--views", default="ortho,persp")
    ap.add_argument("--kind", choices=("f32", "u8"), default="f32")
    ap.add_argument("--settings", default="0.25:1.0,0.5:0.99,0.5:1.0,1:0.99,1:0.995,1:1.0",
                    help="step:early_stop pairs")
    a = ap.parse_args()
    refs = os.path.join(a.data, "reference")
    print("| view | step | early_stop | RMSE | max |")
    print("| --- | --- | --- | --- | --- |")
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
                print(f"| {view} | {step} | {stop} | {e['rmse']:.3f} | {e['max']:.2f} |")


if __name__ == "__main__":
    main()
