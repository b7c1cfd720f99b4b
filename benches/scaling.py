#!/usr/bin/env python3
"""How `--method auto` scales with the number of uncertain values (issue 11's scaling table).

For d = 2, 4, 8, 16, 32, 64 it takes d dimensions of `robots/ur5/ur5.all-values.uncertainty.toml`
(round-robin over the sidecar's patterns, so every d mixes masses, centres of mass, scales and joint
origins), writes them as an explicit sidecar with the same scene, and measures:

- `ribbon analyze` (auto): design, model runs, wall time and peak memory (its summary JSON);
- `ribbon compare --methods auto` against the best reference that exists at that d — a scan of the
  true model for d <= 4, `--reference vertex` above: the docs/method.md §4 error and the share of
  the reference's range the envelope misses.

The fit + bound columns: Y = `stats.bound_seconds` over the wall, U = the surrogate arithmetic's
thread-seconds over threads x wall (README, "What fit + bound means"). Then it fits `runs ~ d^p`
and `wall ~ d^p` by least squares on log-log over d >= 8 and prints a Markdown
table. Run from the repository root after `cargo build --release`:

    python3 benches/scaling.py [--duration 1.0] [--dims 2,4,8,16,32,64] [--out target/scaling]

Wall times come from one run each on whatever machine runs it; compare them within one table only.
"""

import argparse
import json
import math
import os
import subprocess
import sys
from collections import OrderedDict

RIBBON = os.path.join("target", "release", "ribbon")
URDF = os.path.join("robots", "ur5", "ur5.urdf")
ALL_VALUES = os.path.join("robots", "ur5", "ur5.all-values.uncertainty.toml")
SCAN_REFERENCE_MAX_DIM = 4


def run(args):
    done = subprocess.run(args, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(args)} failed ({done.returncode}):\n{done.stderr}")
    return done


def dimensions():
    box = json.loads(run([RIBBON, "params", URDF, "--uncertainty", ALL_VALUES, "--json"]).stdout)
    dims = box["dimensions"] if isinstance(box, dict) else box
    groups = OrderedDict()
    for dim in dims:
        groups.setdefault(dim.get("source", ""), []).append(dim)
    ordered = []
    while any(groups.values()):
        for members in groups.values():
            if members:
                ordered.append(members.pop(0))
    return ordered


def scene_text():
    text = open(ALL_VALUES).read()
    return text[text.index("[scene]"):]


def write_sidecar(path, dims):
    lines = ["[parameters]"]
    for dim in dims:
        lines.append(f'"{dim["name"]}" = [{dim["lower"]!r}, {dim["upper"]!r}]')
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n\n" + scene_text())


def arithmetic_thread_share(summary):
    """U of the README's Speed section: the fit, bound, Sobol' and design-choice thread-seconds
    over (threads x wall), the share of the machine's time spent on surrogate arithmetic."""
    phases = summary["stats"]["phase_seconds"]
    spent = sum(phases.get(k, 0.0) for k in
                ("design_choice", "fit", "inner_bound", "outer_bound", "sobol_indices"))
    return spent / (summary["stats"]["threads"] * summary["wall_seconds"])


def fit_exponent(ds, values):
    xs = [math.log(d) for d in ds]
    ys = [math.log(v) for v in values]
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", default="1.0")
    parser.add_argument("--dims", default="2,4,8,16,32,64")
    parser.add_argument("--out", default=os.path.join("target", "scaling"))
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    all_dims = dimensions()
    rows = []
    for d in [int(x) for x in args.dims.split(",")]:
        sidecar = os.path.join(args.out, f"d{d}.toml")
        write_sidecar(sidecar, all_dims[:d])
        summary = os.path.join(args.out, f"d{d}.json")
        run([RIBBON, "analyze", URDF, "--uncertainty", sidecar, "--duration", args.duration,
             "--summary", summary])
        s = json.load(open(summary))
        reference = "scan" if d <= SCAN_REFERENCE_MAX_DIM else "vertex"
        report = os.path.join(args.out, f"compare-d{d}")
        run([RIBBON, "compare", URDF, "--uncertainty", sidecar, "--duration", args.duration,
             "--methods", "auto", "--orders", "4", "--reference", reference, "--report", report])
        c = json.load(open(os.path.join(report, "compare.json")))
        row = c["rows"][0]
        rows.append({
            "d": d,
            "design": s["design"],
            "runs": s["samples"],
            "wall_s": s["wall_seconds"],
            "peak_mib": s["stats"]["peak_memory_bytes"] / 2**20,
            "bound_share": s["stats"]["bound_seconds"] / s["wall_seconds"],
            "thread_share": arithmetic_thread_share(s),
            "reference": f'{reference} ({c["reference"]["runs"]} runs)',
            "max_error": row["max_error"],
            "mean_error": row["mean_error"],
            "missed": row["max_missed"],
            "check": max(o["relative_misfit"] for o in s["stats"]["check"]["outputs"]) if s["stats"].get("check") else None,
        })
        print(f"d = {d}: {rows[-1]}", file=sys.stderr)
    print("| d | design | runs | wall (s) | fit + bound Y / U | peak memory (MiB) | reference | max error | mean error | missed | largest check misfit |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        check = f'{r["check"]:.2e}' if r["check"] is not None else "-"
        print(f'| {r["d"]} | {r["design"]} | {r["runs"]} | {r["wall_s"]:.2f} | '
              f'{100 * r["bound_share"]:.0f} / {100 * r["thread_share"]:.0f} % | {r["peak_mib"]:.0f} | '
              f'{r["reference"]} | {r["max_error"]:.2e} | {r["mean_error"]:.2e} | {r["missed"]:.2e} | {check} |')
    big = [r for r in rows if r["d"] >= 8]
    if len(big) >= 2:
        ds = [r["d"] for r in big]
        print(f'\nfitted over d >= 8: runs ~ d^{fit_exponent(ds, [r["runs"] for r in big]):.2f}, '
              f'wall ~ d^{fit_exponent(ds, [r["wall_s"] for r in big]):.2f}')


if __name__ == "__main__":
    main()
