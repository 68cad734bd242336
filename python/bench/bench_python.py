#!/usr/bin/env python3
"""What calling hgdeform from Python costs over calling the library from C++ (issue 33: at most
1.05x at a million points).

    PYTHONPATH=build/python python3 python/bench/bench_python.py [--points 1000000] [--repeat 3]

On the same cloud and scenario, alternately: hgdeform.deform(points, scenario) timed from
Python (arrays converted in and out, the report made into a dict), and the same library work
timed in C++ inside the module (hgdeform._hgdeform._cpp_deform_ms: the ScenarioRunner that
deform() runs, on a shape built beforehand). Medians of --repeat runs each, and their ratio.
Then HandleDeformation frames: the time of one drag frame, and the address of the `points`
view before and after (the same: no copy per frame). With --cli PATH, also the command-line
tool's own figures (its report's build + solve + interpolation) on the cloud as a PLY file.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import hgdeform
from hgdeform import _hgdeform


def tube(n, seed=1, length=10.0, radius=1.0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, length, n)
    a = rng.uniform(0.0, 2 * np.pi, n)
    return np.stack([x, radius * np.cos(a), radius * np.sin(a)], axis=1)


SCENARIO = {
    "format": "hgdeform-scenario/1",
    "fixed": [{"box": {"min": [-1, -2, -2], "max": [1.0, 2, 2]}}],
    "manipulated": {"box": {"min": [9.0, -2, -2], "max": [11, 2, 2]}},
    "move": {"drag": {"from": [10, 1, 0], "to": [10, 3, 0]}},
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1000000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--cli", help="the hgdeform program, for its own figures")
    args = parser.parse_args()

    points = tube(args.points)
    print("hgdeform %s, %d points, scenario: base fixed, far end dragged sideways"
          % (hgdeform.__version__, len(points)))
    hgdeform.deform(points, SCENARIO)  # warm-up: pages, caches, libraries
    py_ms, cpp_ms = [], []
    for _ in range(args.repeat):
        t = time.perf_counter()
        out, report = hgdeform.deform(points, SCENARIO)
        py_ms.append(1e3 * (time.perf_counter() - t))
        cpp_ms.append(_hgdeform._cpp_deform_ms(points, SCENARIO, {}))
        print("  python %.1f ms, C++ %.1f ms" % (py_ms[-1], cpp_ms[-1]))
    py, cpp = statistics.median(py_ms), statistics.median(cpp_ms)
    print("deform from Python: %.1f ms; the same work from C++: %.1f ms (medians of %d)"
          % (py, cpp, args.repeat))
    print("ratio Python / C++: %.3f (goal: <= 1.05)" % (py / cpp))
    print("  (report: %d clusters, %d frames, build %.0f ms, solve %.0f ms, interpolation %.0f ms)"
          % (report["clusters"], report["frames"], report["ms"]["build"],
             report["ms"]["solve"], report["ms"]["interpolation"]))

    h = hgdeform.HandleDeformation(points)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    view = h.points
    address = view.__array_interface__["data"][0]
    h.drag([10, 1, 0], [10, 1.05, 0])
    frames, library = [], []
    for k in range(2, 12):
        t = time.perf_counter()
        stats = h.drag([10, 1 + 0.05 * (k - 1), 0], [10, 1 + 0.05 * k, 0])
        frames.append(1e3 * (time.perf_counter() - t))
        library.append(stats["solve_ms"] + stats["interpolation_ms"])
    same = view.__array_interface__["data"][0] == address
    print("HandleDeformation.drag: %.2f ms per frame from Python, of which the library's solve "
          "+ interpolation %.2f ms (medians of %d); the points view at the same address after "
          "them: %s" % (statistics.median(frames), statistics.median(library), len(frames), same))

    if args.cli:
        with tempfile.TemporaryDirectory() as tmp:
            src = os.path.join(tmp, "in.ply")
            hgdeform.write(src, points)
            s = os.path.join(tmp, "s.json")
            with open(s, "w") as f:
                json.dump(SCENARIO, f)
            rep = os.path.join(tmp, "r.json")
            subprocess.run([args.cli, "deform", src, "-s", s, "-o", os.path.join(tmp, "o.ply"),
                            "--report", rep, "-q"], check=True)
            with open(rep) as f:
                ms = json.load(f)["ms"]
            work = ms["build"] - ms["read"] + ms["solve"] + ms["interpolation"]
            print("the command line's own figures: build (without reading) + solve + "
                  "interpolation %.1f ms (read %.0f ms, write %.0f ms)"
                  % (work, ms["read"], ms["write"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
