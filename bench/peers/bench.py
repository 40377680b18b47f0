#!/usr/bin/env python3
"""Runs every peer and volcast interleaved (round-robin over peers, the order rotated at each
repetition), takes medians, compares each peer's image with the reference of the volume it
read, and writes RESULTS/results.md (table), results.csv and speed_vs_error.png.
Usage: bench.py --results DIR [--data DIR] [--reps 5] [--peers volcast,vtk,teem,volpack]
       bench.py --results DIR --peers volcast,vtk --kind u8   (the uint8 volume)
       bench.py --results DIR --plot-only
(run_all.sh installs the peers, makes the volume and the reference first)."""
import argparse
import csv
import json
import os
import platform
import statistics
import subprocess
import sys
import time

import common as C

HERE = os.path.dirname(os.path.abspath(__file__))
PEERS = ("volcast", "vtk", "teem", "volpack")
LABEL = {"volcast": "volcast", "volcast-step1": "volcast, step 1 (opt-in)",
         "volcast-step1-e995": "volcast, step 1, early stop 0.995 (opt-in)",
         "volcast-pre2": "volcast, step 2 pre-integrated (opt-in)", "vtk": "VTK 9.7.2",
         "teem": "teem 1.12", "volpack": "VolPack 1.0b3", "volpack-raw": "VolPack 1.0b3 (from raw)"}
INPUT = {"volpack": "u8", "volpack-raw": "u8"}   # the others read the float32 volume (--kind u8: uint8)


def run_peer(peer, data, images, reps_inside, kind="f32"):
    script = {"volcast": "run_volcast.py", "vtk": "run_vtk.py", "teem": "run_teem.py",
              "volpack": "run_volpack.py"}[peer]
    cmd = [sys.executable, os.path.join(HERE, script), "--data", data, "--out", images]
    if peer in ("vtk", "volpack"):
        cmd += ["--renders", str(reps_inside)]
    if peer in ("volcast", "vtk") and kind != "f32":
        cmd += ["--kind", kind]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        print(f"bench: {peer} failed (exit {r.returncode}):\n{r.stderr[-3000:]}", file=sys.stderr)
        return []
    return [json.loads(line[7:]) for line in r.stdout.splitlines() if line.startswith("RESULT ")]


def error_of(peer, mode, view, images, refs, kind="f32"):
    got = C.load_result(images, peer, mode, view)
    ref = C.load_result(refs, f"ref_{INPUT.get(peer, kind)}", mode, view)
    return C.errors(mode, got, ref)


def machine():
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), "?")
    return f"{os.cpu_count()} CPUs, {cpu}, {platform.system()} {platform.release()}"


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    floor = 1e-3            # errors below this (exact within round-off) are drawn at it
    fig, axes = plt.subplots(1, 4, figsize=(18, 4.8))
    markers = {"volcast": "o", "volcast-step1": "P", "volcast-step1-e995": "*",
               "volcast-pre2": "X", "vtk": "s", "teem": "^",
               "volpack": "D", "volpack-raw": "d"}
    handles = {}
    for ax, mode in zip(axes, C.MODES):
        for i, peer in enumerate(markers):
            pts = [r for r in rows if r["peer"] == peer and r["mode"] == mode]
            if not pts:
                continue
            err = [max((1 - r["iou"]) if mode == "iso" else r["rmse"], floor) for r in pts]
            handles[peer] = ax.scatter(err, [r["seconds"] for r in pts], marker=markers[peer],
                                       color=f"C{i}", label=LABEL[peer])
            for e, r in zip(err, pts):
                ax.annotate(r["view"], (e, r["seconds"]), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(floor / 2, None)
        ax.set_xlabel("1 - IoU of covered pixels" if mode == "iso" else "RMSE (grey levels of 255)")
        ax.set_ylabel("seconds per frame")
        ax.set_title(mode)
        ax.grid(True, which="both", alpha=0.3)
    fig.legend(handles.values(), [LABEL[p] for p in handles], loc="upper right", fontsize=8)
    fig.suptitle(f"Speed against error, 512 x 512, 2 threads (lower left is better; errors < {floor} drawn at {floor})")
    fig.tight_layout(rect=(0, 0, 0.9, 1))
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--results", required=True)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--renders", type=int, default=5, help="warm renders per VTK/VolPack call")
    ap.add_argument("--peers", default=",".join(PEERS))
    ap.add_argument("--plot-only", action="store_true", help="redraw the plot from results.csv")
    ap.add_argument("--kind", choices=("f32", "u8"), default="f32",
                    help="the volume volcast and VTK read: float32 (the benchmark's, default) or "
                         "uint8 (round(255 v), the volume of the issue's first measurements; "
                         "only with --peers volcast,vtk)")
    a = ap.parse_args()
    if a.kind != "f32" and not set(a.peers.split(",")) <= {"volcast", "vtk"}:
        ap.error("--kind u8 runs volcast and VTK only (--peers volcast,vtk)")
    if a.plot_only:
        rows = list(csv.DictReader(open(os.path.join(a.results, "results.csv"))))
        for r in rows:
            for k in ("seconds", "ratio", "rmse", "iou"):
                r[k] = float(r[k])
        plot(rows, os.path.join(a.results, "speed_vs_error.png"))
        return
    images = os.path.join(a.results, "images")
    refs = os.path.join(a.data, "reference")
    os.makedirs(images, exist_ok=True)
    peers = a.peers.split(",")
    records = []
    for rep in range(a.reps):
        order = peers[rep % len(peers):] + peers[:rep % len(peers)]
        for peer in order:
            start = time.time()
            got = run_peer(peer, a.data, images, a.renders, a.kind)
            for r in got:
                r["rep"] = rep
            records += got
            print(f"bench: repetition {rep + 1}/{a.reps}: {peer}: {len(got)} cases, {time.time() - start:.0f} s", flush=True)
    json.dump(records, open(os.path.join(a.results, "timings.json"), "w"), indent=1)

    cases = sorted({(r["peer"], r["mode"], r["view"]) for r in records},
                   key=lambda c: (C.VIEWS.index(c[2]), C.MODES.index(c[1]), list(LABEL).index(c[0])))
    times = {c: [r["seconds"] for r in records if (r["peer"], r["mode"], r["view"]) == c] for c in cases}
    secs = {c: statistics.median(t) for c, t in times.items()}
    rows = []
    for peer, mode, view in cases:
        e = error_of(peer, mode, view, images, refs, a.kind)
        base = secs.get(("volcast", mode, view))
        rows.append(dict(peer=peer, mode=mode, view=view, seconds=secs[(peer, mode, view)],
                         ratio=secs[(peer, mode, view)] / base if base else float("nan"),
                         rmse=e["rmse"], iou=e.get("iou", float("nan")),
                         reps=len(times[(peer, mode, view)]), fastest=min(times[(peer, mode, view)]),
                         slowest=max(times[(peer, mode, view)])))
    with open(os.path.join(a.results, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    volume = "" if a.kind == "f32" else f"; volume {a.kind} (volcast and VTK)"
    lines = [f"Peer benchmark, {time.strftime('%Y-%m-%d %H:%M')}, {machine()}; volcast = "
             f"{os.environ.get('VOLCAST', '/work/main/target/release/volcast')}; {a.reps} repetitions, medians{volume}.",
             "", "| view | mode | peer | seconds per frame | (fastest - slowest) | ratio to volcast | error vs reference |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        err = f"IoU {r['iou']:.3f}, shade RMSE {r['rmse']:.2f}" if r["mode"] == "iso" else f"RMSE {r['rmse']:.3f}"
        lines.append(f"| {r['view']} | {r['mode']} | {LABEL[r['peer']]} | {r['seconds']:.3f} | "
                     f"{r['fastest']:.3f} - {r['slowest']:.3f} | {r['ratio']:.2f} | {err} |")
    table = "\n".join(lines) + "\n"
    open(os.path.join(a.results, "results.md"), "w").write(table)
    print(table)
    try:
        plot(rows, os.path.join(a.results, "speed_vs_error.png"))
    except ImportError:
        print("bench: matplotlib missing: no plot", file=sys.stderr)


if __name__ == "__main__":
    main()
