#!/usr/bin/env python3
"""The cost of a study from Python against the CLI, same study, same machine: the median wall time
of REPEATS alternating runs of `ribbon analyze ROBOT` (a process, no output files) and
`ribbon.analyze(ROBOT)` (in this process), and their ratio. Not a test: speed is measured, not
asserted (run it from the repository root with the package installed).

    python python/tests/bench_analyze.py [--repeats 5] [ROBOT …]
"""

import argparse
import os
import statistics
import subprocess
import sys
import time

import ribbon

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("robots", nargs="*", default=["ur5", "slider_crank", "four_bar"])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "ribbon"))
    args = parser.parse_args()
    print(f"| study | CLI `ribbon analyze` (median of {args.repeats}) | `ribbon.analyze` | ratio |")
    print("|---|---|---|---|")
    for name in args.robots:
        urdf = os.path.join(ROOT, "robots", name, f"{name}.urdf")
        cli_s, py_s = [], []
        for _ in range(args.repeats):
            started = time.perf_counter()
            subprocess.run([args.bin, "analyze", urdf], check=True, capture_output=True)
            cli_s.append(time.perf_counter() - started)
            started = time.perf_counter()
            study = ribbon.analyze(urdf)
            py_s.append(time.perf_counter() - started)
        cli, py = statistics.median(cli_s), statistics.median(py_s)
        print(f"| {name} ({study.runs} runs, {study.times[-1]:g} s) | {cli:.3f} s | {py:.3f} s "
              f"| {py / cli:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
