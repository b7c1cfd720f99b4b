"""Reference trajectories for the HHT convergence tests: Pinocchio ABA + classical RK4.

Usage (reference venv):
    python tests/reference/rk4_reference.py URDF --gravity 0,-9.81,0 --duration 1 --step 1e-5 \
        --times 0.25,0.5,0.75,1.0 --out tests/fixtures/rk4/NAME.json

The robot starts at q = 0 (angles; continuous joints as cos/sin = 1/0 in Pinocchio) with v = 0 and
falls passively under the given gravity (no damping, no friction: Pinocchio's aba ignores them). RK4
stages advance the configuration with pin.integrate, so continuous joints stay on their circle.
Positions are written as one angle per joint (atan2 for continuous joints), in Pinocchio's joint
order, with the joint names so that the Rust side maps them by name.
"""
import argparse
import json
import math

import numpy as np
import pinocchio as pin

from pin_dynamics import fnv1a64  # the same hash as tests/common/mod.rs


def angles(model, q):
    out = {}
    for j in range(1, model.njoints):
        name = model.names[j]
        iq, nq = model.idx_qs[j], model.nqs[j]
        if nq == 1:
            out[name] = float(q[iq])
        elif nq == 2:
            out[name] = float(math.atan2(q[iq + 1], q[iq]))
        else:
            raise SystemExit(f"joint {name}: nq = {nq} is not handled by this script")
    return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("urdf")
    parser.add_argument("--gravity", required=True)
    parser.add_argument("--duration", type=float, default=1.0)
    parser.add_argument("--step", type=float, default=1e-5)
    parser.add_argument("--times", default="0.25,0.5,0.75,1.0")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()

    model = pin.buildModelFromUrdf(args.urdf)
    model.gravity.linear = np.array([float(x) for x in args.gravity.split(",")])
    data = model.createData()
    q = pin.neutral(model)
    v = np.zeros(model.nv)
    tau = np.zeros(model.nv)
    h = args.step
    n_steps = int(round(args.duration / h))
    wanted = [float(t) for t in args.times.split(",")]
    record_at = {int(round(t / h)): t for t in wanted}

    def accel(q_, v_):
        return pin.aba(model, data, q_, v_, tau).copy()

    records = []
    for k in range(n_steps + 1):
        if k in record_at:
            records.append({"t": record_at[k], "q": angles(model, q)})
        if k == n_steps:
            break
        a1 = accel(q, v)
        q2, v2 = pin.integrate(model, q, 0.5 * h * v), v + 0.5 * h * a1
        a2 = accel(q2, v2)
        q3, v3 = pin.integrate(model, q, 0.5 * h * v2), v + 0.5 * h * a2
        a3 = accel(q3, v3)
        q4, v4 = pin.integrate(model, q, h * v3), v + h * a3
        a4 = accel(q4, v4)
        q = pin.integrate(model, q, h / 6.0 * (v + 2 * v2 + 2 * v3 + v4))
        v = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)

    result = {
        "urdf": args.urdf,
        "urdf_fnv1a64": fnv1a64(open(args.urdf, "rb").read()),
        "gravity": [float(x) for x in args.gravity.split(",")],
        "method": "pinocchio aba + RK4",
        "pinocchio": pin.__version__,
        "step": h,
        "records": records,
    }
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
