#!/usr/bin/env python3
"""Compare two envelope CSVs of `ribbon analyze --csv` (issue 40): per output, the largest
|difference| of its lower, nominal and upper columns over its width (the largest upper − lower
of the first CSV over time), and where it is. Prints one line per output, largest first.

    python3 scripts/compare_envelopes.py BEFORE.csv AFTER.csv [--limit 1e-3]

Exit status 1 if any output moved by more than --limit of its width (default 1e-3, the 0.1 % of
issue 40), 2 if the files do not have the same columns and times.
"""
import csv
import sys


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], [[float(v) for v in row] for row in rows[1:]]


def main():
    args = sys.argv[1:]
    limit = 1e-3
    if "--limit" in args:
        i = args.index("--limit")
        limit = float(args[i + 1])
        del args[i : i + 2]
    if len(args) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    (head_a, rows_a), (head_b, rows_b) = read(args[0]), read(args[1])
    if head_a != head_b or len(rows_a) != len(rows_b):
        print(f"different columns or row counts: {len(head_a)}/{len(head_b)} columns, "
              f"{len(rows_a)}/{len(rows_b)} rows", file=sys.stderr)
        return 2
    if any(a[0] != b[0] for a, b in zip(rows_a, rows_b)):
        print("different record times", file=sys.stderr)
        return 2
    outputs = [h[: -len(".lower")] for h in head_a if h.endswith(".lower")]
    col = {h: i for i, h in enumerate(head_a)}
    report = []
    for name in outputs:
        lo, hi = col[name + ".lower"], col[name + ".upper"]
        width = max(r[hi] - r[lo] for r in rows_a)
        worst, where = 0.0, None
        for side in ("lower", "nominal", "upper"):
            c = col[f"{name}.{side}"]
            for a, b in zip(rows_a, rows_b):
                diff = abs(a[c] - b[c])
                if diff > worst:
                    worst, where = diff, (side, a[0], a[c], b[c])
        rel = worst / width if width > 0 else (0.0 if worst == 0 else float("inf"))
        report.append((rel, name, worst, width, where))
    report.sort(reverse=True)
    for rel, name, worst, width, where in report:
        at = "" if where is None else (
            f" ({where[0]} at t = {where[1]:g}: {where[2]:.9g} -> {where[3]:.9g})")
        print(f"{name}: max |diff| {worst:.3e}, width {width:.3e}, {rel:.2e} of the width{at}")
    worst = report[0][0] if report else 0.0
    print(f"largest: {worst:.2e} of a width (limit {limit:g})")
    return 1 if worst > limit else 0


if __name__ == "__main__":
    sys.exit(main())
