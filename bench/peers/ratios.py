#!/usr/bin/env python3
"""volcast's time over VTK's in each repetition of a peer benchmark run, and their
median per view and mode (the README's "per repetition" table): the machine's speed
drifts between repetitions, so same-repetition ratios are steadier than ratios of
medians.

    python3 bench/peers/ratios.py RESULTS_DIR/timings.json
"""
import json
import statistics
import sys
from collections import defaultdict


def main(path):
    seconds = defaultdict(dict)
    for r in json.load(open(path)):
        seconds[(r["view"], r["mode"], r["peer"])][r["rep"]] = r["seconds"]
    print("| view | mode | volcast / VTK per repetition | median |")
    print("| --- | --- | --- | --- |")
    cases = [(m, "volcast") for m in ("mip", "xray", "composite", "iso")]
    cases[3:3] = [("composite", "volcast-step1"), ("composite", "volcast-step1-e995")]
    for view in ("ortho", "persp"):
        for mode, peer in cases:
            ours = seconds.get((view, mode, peer), {})
            vtk = seconds.get((view, mode, "vtk"), {})
            reps = sorted(set(ours) & set(vtk))
            if not reps:
                continue
            ratios = [ours[k] / vtk[k] for k in reps]
            listed = ", ".join(f"{x:.2f}" for x in ratios)
            name = mode if peer == "volcast" else f"{mode} ({peer})"
            print(f"| {view} | {name} | {listed} | {statistics.median(ratios):.2f} |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
