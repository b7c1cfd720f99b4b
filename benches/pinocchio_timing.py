#!/usr/bin/env python3
"""Pinocchio's crba, rnea and aba timed from Python: the reference for ribbon's criterion benches.

Usage (from the crate root; the venv is the one tests/common/mod.rs creates for the parity tests,
`cargo test --release --test pinocchio_parity` makes it):

    target/reference-venv/bin/python benches/pinocchio_timing.py [--number N] [--repeat R] [URDF ...]

Without URDFs it times example-robot-data's ur5 and panda and, when it exists, robots/ur5/ur5.urdf.
Prints JSON on stdout: per robot, µs per call of crba, rnea, aba, both raw and net of the binding
overhead.

Method: each call is timed with timeit (N calls per run, the minimum over R runs, so that another
process on the machine inflates nothing), at one fixed random state (seed 0; q uniform in [-π, π]
within the limits, v, tau, qdd standard normal), with the model and data built once. Every call from
Python also pays the boost::python dispatch and the numpy → Eigen conversion of its arguments
(~0.3–0.5 µs): we time a trivial binding call with the same kind of arguments,
pin.isNormalized(model, q) (one loop over the joints that does nothing for revolute joints), and
subtract it. The net numbers are what ribbon's Rust benches (no such overhead) compare with. The
subtraction is approximate: rnea and aba convert three vectors where the trivial call converts one.
"""

import json
import math
import os
import sys
import timeit

import numpy as np
import pinocchio as pin


def erd_urdf(loader_name):
    from example_robot_data import robots_loader
    import sysconfig

    loader = robots_loader.ROBOTS[loader_name]
    for base in [sysconfig.get_paths()["purelib"]] + sys.path:
        path = os.path.join(base, "cmeel.prefix", "share", "example-robot-data", "robots",
                            loader.path, loader.urdf_subpath, loader.urdf_filename)
        if os.path.isfile(path):
            return path
    sys.exit(f"pinocchio_timing.py: example-robot-data's {loader_name} URDF not found")


def best_us(stmt, number, repeat):
    return min(timeit.repeat(stmt, number=number, repeat=repeat)) / number * 1e6


def time_robot(label, path, number, repeat):
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    rng = np.random.default_rng(0)
    lower = np.maximum(model.lowerPositionLimit, -math.pi)
    upper = np.minimum(model.upperPositionLimit, math.pi)
    q = rng.uniform(lower, upper)
    q = pin.normalize(model, q)  # continuous joints: (cos, sin) pairs back on the circle
    v, tau, qdd = (rng.normal(size=model.nv) for _ in range(3))

    def trivial():
        return best_us(lambda: pin.isNormalized(model, q), number, repeat)

    overhead_before = trivial()
    raw = {
        "crba": best_us(lambda: pin.crba(model, data, q), number, repeat),
        "rnea": best_us(lambda: pin.rnea(model, data, q, v, qdd), number, repeat),
        "aba": best_us(lambda: pin.aba(model, data, q, v, tau), number, repeat),
    }
    overhead = min(overhead_before, trivial())  # the first runs also warm caches up
    return {
        "robot": label,
        "urdf": path,
        "nq": model.nq,
        "nv": model.nv,
        "binding_overhead_us": overhead,
        "raw_us": raw,
        "net_us": {k: max(t - overhead, 0.0) for k, t in raw.items()},
    }


def main(argv):
    number, repeat, urdfs = 20000, 7, []
    i = 0
    while i < len(argv):
        flag, _, inline = argv[i].partition("=")
        if flag in ("--number", "--repeat"):
            if not inline:
                i += 1
                inline = argv[i]
            if flag == "--number":
                number = int(inline)
            else:
                repeat = int(inline)
        elif flag in ("-h", "--help"):
            print(__doc__)
            return
        else:
            urdfs.append((os.path.splitext(os.path.basename(argv[i]))[0], argv[i]))
        i += 1
    if not urdfs:
        urdfs = [("ur5 (example-robot-data)", erd_urdf("ur5")), ("panda (example-robot-data)", erd_urdf("panda"))]
        if os.path.isfile("robots/ur5/ur5.urdf"):
            urdfs.append(("ur5 (robots/ur5)", "robots/ur5/ur5.urdf"))
    results = [time_robot(label, path, number, repeat) for label, path in urdfs]
    print(json.dumps({
        "pinocchio_version": pin.__version__,
        "method": f"timeit, min of {repeat} runs of {number} calls; net = raw - pin.isNormalized(model, q)",
        "results": results,
    }, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
