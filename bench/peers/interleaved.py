#!/usr/bin/env python3
"""Interleaved before/after timing of volcast binaries on one peer scene (not in CI).

Each repetition runs every binary in turn, as whole processes, on the scene of
bench/peers/scenes/ (its data folder substituted, its orbit lengthened to N frames):
seconds per frame = (T(--frames 0..N) - T(--frames 0..1)) / (N - 1), CPU (user + system
of the process) and wall. Prints the medians, each binary's CPU median over the first's,
and every repetition's wall time.

Usage: interleaved.py SCENE BINARY [BINARY ...] [--data DIR] [--reps R] [--threads T] [--frames N] [--u8]
                      [--mode MODE] [--degrees D] [--set KEY=VALUE]
  e.g. interleaved.py ortho_composite /tmp/volcast-before target/release/volcast --frames 6
  --mode and --degrees replace the pass's mode and the orbit's degrees (e.g. a MinIP turntable of
  the peer volume: ortho_mip --mode minip --degrees 360); --set adds a line to the pass (e.g.
  --set depth_cue=0.5).
"""
import argparse
import os
import re
import resource
import shutil
import statistics
import subprocess
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", help="a scene of bench/peers/scenes/, e.g. ortho_composite")
    ap.add_argument("binaries", nargs="+")
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--threads", default="2")
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--u8", action="store_true",
                    help="render the uint8 volume (window [0, 255]) instead of the float32 one")
    ap.add_argument("--mode", help="the pass's mode instead of the scene's")
    ap.add_argument("--degrees", type=float, help="the orbit's degrees instead of the scene's")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a line added to the pass (repeatable)")
    a = ap.parse_args()
    work = tempfile.mkdtemp()
    try:
        text = open(os.path.join(HERE, "scenes", a.scene + ".toml")).read()
        text = text.replace("/work/peers-data", a.data)
        text = re.sub(r"(?m)^frames = \d+", f"frames = {a.frames}", text)
        if a.u8:
            text = text.replace("volume_f32.nrrd", "volume_u8.nrrd")
            text = re.sub(r"(?m)^window = .*", "window = [0.0, 255.0]", text)
        if a.degrees is not None:
            text, k = re.subn(r"(?m)^degrees = .*", f"degrees = {a.degrees}", text)
            assert k == 1, "the scene has one orbit `degrees` line"
        if a.mode is not None or a.set:
            lines = [f'mode = "{a.mode}"'] if a.mode is not None else []
            if a.mode is None:
                lines.append(re.search(r'(?m)^mode = .*', text).group(0))
            lines += [kv.replace("=", " = ", 1) for kv in a.set]
            text, k = re.subn(r'(?m)^mode = .*', "\n".join(lines), text)
            assert k == 1, "the scene has one pass with a `mode` line"
        scene = os.path.join(work, a.scene + ".toml")
        open(scene, "w").write(text)
        out = os.path.join(work, "out")

        def run(binary, n):
            shutil.rmtree(out, ignore_errors=True)
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            w0 = time.perf_counter()
            subprocess.run([binary, "render", scene, "--out", out, "--quiet", "--no-view-reuse",
                            "--threads", a.threads, "--frames", f"0..{n}"],
                           check=True, stdout=subprocess.DEVNULL)
            w1 = time.perf_counter()
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime
            return cpu, w1 - w0

        n = a.frames
        res = {b: ([], []) for b in a.binaries}
        for _ in range(a.reps):
            for b in a.binaries:
                c1, w1 = run(b, 1)
                cn, wn = run(b, n)
                res[b][0].append((cn - c1) / (n - 1))
                res[b][1].append((wn - w1) / (n - 1))
        base = statistics.median(res[a.binaries[0]][0])
        for b in a.binaries:
            c = statistics.median(res[b][0])
            w = statistics.median(res[b][1])
            walls = " ".join(f"{x:.3f}" for x in res[b][1])
            print(f"{b:40s} cpu {c:.4f} (fastest {min(res[b][0]):.4f}) wall {w:.4f} "
                  f"cpu/first {c / base:.3f}  walls {walls}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
