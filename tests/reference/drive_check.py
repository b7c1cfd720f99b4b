"""Drives give inverse dynamics: compare ribbon's drive efforts with Pinocchio's rnea.

Usage (reference venv):
    python tests/reference/drive_check.py URDF CSV SPEC.json

CSV: ribbon simulate output with columns t, q.J, v.J, qdd.J and effort.J for every joint J (fixed base,
1-dof joints). SPEC.json: {"gravity": [gx, gy, gz], "drives": {J: {"offset", "amplitude",
"frequency", "phase"}}, "settle_time": T} — sine profiles q = offset + amplitude sin(2π f t + phase).
The start value a_0 = q̈_0 of the generalized-α scheme leaves an O(h) transient in q̈ (and so in the
efforts) that the numerical damping removes within a few dozen steps; errors are reported over the
whole run and over t ≥ settle_time.

Prints JSON: the largest ‖effort − τ‖∞ relative to max_t ‖τ‖∞, against (a) rnea at the simulated
(q, q̇, q̈) and (b) rnea at the analytic trajectory.
"""
import csv
import json
import math
import sys

import numpy as np
import pinocchio as pin


def main():
    urdf, csv_path, spec_path = sys.argv[1:4]
    spec = json.load(open(spec_path))
    model = pin.buildModelFromUrdf(urdf)
    model.gravity.linear = np.array(spec["gravity"], dtype=float)
    data = model.createData()
    names = [model.names[j] for j in range(1, model.njoints)]
    for j in range(1, model.njoints):
        if model.nqs[j] != 1:
            raise SystemExit(f"joint {model.names[j]} has nq = {model.nqs[j]}; this check takes 1-dof joints")
    rows = list(csv.DictReader(open(csv_path)))
    settle = float(spec.get("settle_time", 0.0))
    simulated_error, analytic_error, settled_error, tau_scale = 0.0, 0.0, 0.0, 0.0
    for row in rows:
        t = float(row["t"])
        q = np.array([float(row[f"q.{n}"]) for n in names])
        v = np.array([float(row[f"v.{n}"]) for n in names])
        a = np.array([float(row[f"qdd.{n}"]) for n in names])
        effort = np.array([float(row[f"effort.{n}"]) for n in names])
        tau_sim = pin.rnea(model, data, q, v, a).copy()
        qa, va, aa = [], [], []
        for n in names:
            d = spec["drives"][n]
            w = 2 * math.pi * d["frequency"]
            s, c = math.sin(w * t + d["phase"]), math.cos(w * t + d["phase"])
            qa.append(d["offset"] + d["amplitude"] * s)
            va.append(d["amplitude"] * w * c)
            aa.append(-d["amplitude"] * w * w * s)
        tau_exact = pin.rnea(model, data, np.array(qa), np.array(va), np.array(aa)).copy()
        tau_scale = max(tau_scale, np.abs(tau_exact).max())
        simulated_error = max(simulated_error, np.abs(effort - tau_sim).max())
        analytic_error = max(analytic_error, np.abs(effort - tau_exact).max())
        if t >= settle:
            settled_error = max(settled_error, np.abs(effort - tau_exact).max())
    print(json.dumps({
        "rows": len(rows),
        "tau_scale": tau_scale,
        "relative_error_simulated_state": simulated_error / max(tau_scale, 1.0),
        "relative_error_analytic_trajectory": analytic_error / max(tau_scale, 1.0),
        "relative_error_analytic_after_settling": settled_error / max(tau_scale, 1.0),
    }))


if __name__ == "__main__":
    main()
