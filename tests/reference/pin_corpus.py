#!/usr/bin/env python3
"""Pinocchio's verdict and dynamics on every URDF of a corpus, in one process.

For each `.urdf` under CORPUS (sorted by relative path), with a fixed base and with a free-flyer
root named `root_joint`: whether Pinocchio 4.1 loads it (`pin.buildModelFromUrdf`) and, if not, its
message and what urdfdom printed; if it loads, the joint layout in ribbon's conventions and, at
N random states, the mass matrix (crba, symmetrised), the bias (nle), forward dynamics (aba),
inverse dynamics (rnea) and the world placement of every link (BODY frames). tests/urdf_corpus.rs
runs this once and compares ribbon with it.

Usage (from the crate root, with the reference venv of tests/common/mod.rs):

    target/reference-venv/bin/python tests/reference/pin_corpus.py \\
        --corpus tests/urdf_corpus --states 3 --seed 0 --out target/urdf-corpus/reference.json

Conventions are those of tests/reference/pin_dynamics.py (continuous joints have one coordinate,
the angle; a free flyer is x y z, quaternion x y z w; v linear then angular in the body frame;
mimic joints independent; gravity (0, 0, -9.81)). A URDF `floating` joint is a free flyer too.
Random states: revolute q uniform in [-pi, pi] intersected with Pinocchio's position limits,
continuous in [-pi, pi], prismatic in [-0.5, 0.5] m intersected with the limits, free flyers a
position in [-1, 1]^3 and a uniformly random unit quaternion; v, tau, qdd standard normal; numpy's
default_rng([seed, file index, base]) per model. A model whose aba is not finite (a singular mass
matrix) has `qdd: null`; every state has `mass_matrix_eigenvalue_ratio`, the smallest eigenvalue of
Pinocchio's mass matrix over its largest (how close to singular it is).
"""

import json
import math
import os
import sys
import tempfile

import numpy as np
import pinocchio as pin

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pin_dynamics import (  # noqa: E402  (the shared conventions)
    DEFAULT_ANGLE_RANGE,
    DEFAULT_PRISMATIC_RANGE_M,
    GRAVITY,
    fnv1a64,
    sample_range,
    to_json,
)


def parse_args(argv):
    options = {"corpus": None, "states": 3, "seed": 0, "out": None}
    for arg in argv:
        key, sep, value = arg.partition("=")
        if not sep or key[2:] not in options:
            sys.exit(f"pin_corpus.py: unknown argument {arg!r}; use --corpus=DIR --states=N --seed=S --out=FILE")
        options[key[2:]] = value
    if options["corpus"] is None or options["out"] is None:
        sys.exit("pin_corpus.py: --corpus=DIR and --out=FILE are required")
    options["states"] = int(options["states"])
    options["seed"] = int(options["seed"])
    return options


def load_capturing_stderr(path, floating):
    """Loads a model; returns (model or None, exception text, what urdfdom printed on fd 2)."""
    with tempfile.TemporaryFile(mode="w+b") as capture:
        saved = os.dup(2)
        os.dup2(capture.fileno(), 2)
        try:
            if floating:
                model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer(), "root_joint")
            else:
                model = pin.buildModelFromUrdf(path)
            error = None
        except Exception as e:  # Pinocchio raises ValueError/RuntimeError for bad files
            model, error = None, str(e).strip()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        capture.seek(0)
        printed = capture.read().decode("utf-8", "replace")
    lines = [l.strip() for l in printed.splitlines() if l.strip() and not l.strip().startswith("at line")]
    return model, error, lines


def joint_kind(joint_model):
    """ribbon's type for a Pinocchio joint, or None when ribbon has no equivalent. An unbounded
    revolute joint (nq = 2: cos, sin) is continuous, whatever its axis."""
    name = joint_model.shortname()
    if name == "JointModelFreeFlyer":
        return "floating"
    if (joint_model.nq, joint_model.nv) == (2, 1) and "Revolute" in name or name.startswith("JointModelRUB"):
        return "continuous"
    if joint_model.nq == 1 and (name in ("JointModelRX", "JointModelRY", "JointModelRZ") or name == "JointModelRevoluteUnaligned"):
        return "revolute"
    if joint_model.nq == 1 and (name in ("JointModelPX", "JointModelPY", "JointModelPZ") or name == "JointModelPrismaticUnaligned"):
        return "prismatic"
    return None


def reference_for_model(model, seed, n_states):
    model.gravity = pin.Motion(np.array(GRAVITY), np.zeros(3))
    data = model.createData()
    joints, q_at = [], 0
    for j in range(1, model.njoints):
        kind = joint_kind(model.joints[j])
        if kind is None:
            return {"ribbon_conversion": f"joint {model.names[j]!r} is a {model.joints[j].shortname()}, which ribbon does not have"}
        nq = 7 if kind == "floating" else 1
        joints.append({"name": model.names[j], "type": kind, "q_index": q_at, "nq": nq,
                       "v_index": model.idx_vs[j], "nv": model.nvs[j], "pin_q_index": model.idx_qs[j]})
        q_at += nq
    links = [f.name for f in model.frames if f.type == pin.BODY]
    frame_ids = {name: model.getFrameId(name, pin.BODY) for name in links}
    rng = np.random.default_rng(seed)
    states = []
    for _ in range(n_states):
        q_ribbon, q_pin = np.zeros(q_at), np.zeros(model.nq)
        for jt in joints:
            qi, pi = jt["q_index"], jt["pin_q_index"]
            if jt["type"] == "floating":
                quat = rng.normal(size=4)
                quat /= np.linalg.norm(quat)
                q_ribbon[qi:qi + 7] = np.concatenate([rng.uniform(-1.0, 1.0, 3), quat])
                q_pin[pi:pi + 7] = q_ribbon[qi:qi + 7]
            elif jt["type"] == "continuous":
                theta = rng.uniform(*DEFAULT_ANGLE_RANGE)
                q_ribbon[qi] = theta
                q_pin[pi:pi + 2] = (math.cos(theta), math.sin(theta))
            else:
                default = DEFAULT_ANGLE_RANGE if jt["type"] == "revolute" else DEFAULT_PRISMATIC_RANGE_M
                lower, upper = model.lowerPositionLimit[pi], model.upperPositionLimit[pi]
                q_ribbon[qi] = rng.uniform(*sample_range(default, lower, upper))
                q_pin[pi] = q_ribbon[qi]
        v, tau, qdd = rng.normal(size=model.nv), rng.normal(size=model.nv), rng.normal(size=model.nv)
        mass = pin.crba(model, data, q_pin)
        mass = np.triu(mass) + np.triu(mass, 1).T
        bias = pin.nonLinearEffects(model, data, q_pin, v).copy()
        with np.errstate(all="ignore"):
            aba = pin.aba(model, data, q_pin, v, tau).copy()
        rnea = pin.rnea(model, data, q_pin, v, qdd).copy()
        pin.framesForwardKinematics(model, data, q_pin)
        frames = {name: {"position": data.oMf[fid].translation.tolist(), "rotation": data.oMf[fid].rotation.tolist()}
                  for name, fid in frame_ids.items()}
        finite = bool(np.all(np.isfinite(aba)))
        eigenvalues = np.linalg.eigvalsh(mass) if model.nv else np.ones(1)
        ratio = float(eigenvalues[0] / eigenvalues[-1]) if eigenvalues[-1] > 0 else 0.0
        states.append({"q": q_ribbon.tolist(), "v": v.tolist(), "tau": tau.tolist(), "qdd": qdd.tolist(),
                       "mass_matrix_eigenvalue_ratio": ratio,
                       "expected": {"mass_matrix": mass.tolist(), "bias": bias.tolist(),
                                    "qdd": aba.tolist() if finite else None, "tau": rnea.tolist(), "frames": frames}})
    return {"nq": q_at, "nv": model.nv, "joints": joints, "links": links, "states": states}


def main(argv):
    options = parse_args(argv)
    corpus = options["corpus"]
    files = []
    for dirpath, _, names in os.walk(corpus):
        files += [os.path.relpath(os.path.join(dirpath, n), corpus) for n in names if n.endswith(".urdf")]
    files.sort()
    results = []
    for index, relative in enumerate(files):
        path = os.path.join(corpus, relative)
        with open(path, "rb") as f:
            digest = fnv1a64(f.read())
        for base, floating in enumerate((False, True)):
            model, error, printed = load_capturing_stderr(path, floating)
            entry = {"file": relative, "floating": floating, "urdf_fnv1a64": digest,
                     "loaded": model is not None, "message": error, "urdfdom_printed": printed}
            if model is not None:
                entry.update(reference_for_model(model, [options["seed"], index, base], options["states"]))
            results.append(entry)
    reference = {"generator": "tests/reference/pin_corpus.py", "command": ["tests/reference/pin_corpus.py"] + list(argv),
                 "pinocchio_version": pin.__version__, "seed": options["seed"], "states_per_model": options["states"],
                 "gravity": list(GRAVITY), "files": results}
    out = options["out"]
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out + ".tmp", "w") as f:
        f.write(to_json(reference) + "\n")
    os.replace(out + ".tmp", out)


if __name__ == "__main__":
    main(sys.argv[1:])
