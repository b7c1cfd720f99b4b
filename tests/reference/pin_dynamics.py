#!/usr/bin/env python3
"""Reference rigid-body dynamics from Pinocchio, in ribbon's coordinate conventions.

Writes one JSON file with, for each robot, N random states and what Pinocchio computes there:
the mass matrix (crba, symmetrised), the bias C(q,v)v + g(q) (nle), forward dynamics (aba: qdd
from tau), inverse dynamics (rnea: tau from qdd) and the world placement of every URDF link
(framesForwardKinematics, the link's BODY frame). tests/pinocchio_parity.rs feeds the same states
to `ribbon dynamics … --json` and compares; tests/fixtures/pinocchio/*.json are outputs of this
script, committed so that the comparison also runs without Python.

Usage (from the crate root, with the reference venv that tests/common/mod.rs creates):

    target/reference-venv/bin/python tests/reference/pin_dynamics.py \
        --seed 0 --states 20 --out target/ref.json \
        --robot erd:ur5 \
        --robot erd:solo12 --floating \
        --robot robots/ur5/ur5.urdf --name ur5_mass --set link.forearm_link.mass=2.5

`--seed`, `--states`, `--out` are global. Each `--robot URDF` starts a robot; the options after it
(`--name LABEL`, `--floating`, `--set PATH=VALUE`, repeatable) apply to that robot. URDF is a path
(written to the output as given, so relative paths stay relative to the working directory) or
`erd:NAME`, a robot of example-robot-data (NAME as in example_robot_data.load(NAME), or the stem
of one of its URDF files, `erd:talos_left_arm`), written as an absolute path. `--erd-dir` alone prints example-robot-data's robots directory and exits.

Conventions (ribbon's, see the design's "Command-line and JSON" contract):
- Coordinates are listed per joint in Pinocchio's joint order (the reference's `joints` list gives
  name, type, q_index, nq, v_index, nv of each in these vectors); the consumer maps by joint name.
- Continuous joints have one coordinate, the angle θ (Pinocchio stores cos θ, sin θ).
- A floating base (`--floating`) is Pinocchio's free flyer named `root_joint`: q = x y z, quaternion
  x y z w; v = linear then angular velocity in the base frame; its qdd is the spatial acceleration
  in the base frame as aba returns it.
- Mimic joints are independent coordinates (Pinocchio's default, mimic=False). Gravity (0, 0, -9.81).
- Random states: revolute q uniform in [-π, π] intersected with the joint's limits, continuous in
  [-π, π], prismatic in [-0.5, 0.5] m intersected with the limits; a floating base gets a position
  uniform in [-1, 1]³ and a uniformly random unit quaternion; v, tau, qdd are standard normal.
  numpy's default_rng(seed), one stream per robot (seeded with [seed, robot index]).

`--set PATH=VALUE` edits the URDF text before Pinocchio parses it (pin.buildModelFromXML):
  link.NAME.mass                          <link name=NAME><inertial><mass value>
  link.NAME.com.{x,y,z}                   <link name=NAME><inertial><origin xyz> component
  link.NAME.inertia.{ixx,ixy,ixz,iyy,iyz,izz}   <link name=NAME><inertial><inertia ATTR>
  joint.NAME.origin.{x,y,z,roll,pitch,yaw}      <joint name=NAME><origin xyz|rpy> component
The reference records each set with the URDF value it replaced, so that the consumer passes the
same `--set` flags to ribbon and can check that the perturbation changed something.
"""

import json
import math
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

GRAVITY = (0.0, 0.0, -9.81)
DEFAULT_ANGLE_RANGE = (-math.pi, math.pi)
DEFAULT_PRISMATIC_RANGE_M = (-0.5, 0.5)


def fnv1a64(data: bytes) -> str:
    """FNV-1a 64-bit hash as 16 hex digits (tests/common/mod.rs computes the same)."""
    h = 0xCBF29CE484222325
    for byte in data:
        h ^= byte
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return f"{h:016x}"


def erd_robots_dir() -> str:
    """example-robot-data's robots directory, as shipped by the example-robot-data wheel."""
    import sysconfig

    candidates = [
        os.path.join(sysconfig.get_paths()["purelib"], "cmeel.prefix", "share", "example-robot-data", "robots")
    ]
    for p in sys.path:
        candidates.append(os.path.join(p, "cmeel.prefix", "share", "example-robot-data", "robots"))
    for c in candidates:
        if os.path.isdir(c):
            return os.path.abspath(c)
    sys.exit(f"pin_dynamics.py: example-robot-data's robots directory not found (looked in {candidates})")


def resolve_erd(name: str) -> str:
    """URDF path of example_robot_data.load(name), without loading it; failing that, the one
    URDF of example-robot-data whose file stem is `name` (`talos_left_arm`)."""
    from example_robot_data import robots_loader

    robots_dir = erd_robots_dir()
    loader = robots_loader.ROBOTS.get(name)
    if loader is not None and getattr(loader, "urdf_filename", ""):
        path = os.path.join(robots_dir, loader.path, loader.urdf_subpath, loader.urdf_filename)
        if not os.path.isfile(path):
            sys.exit(f"pin_dynamics.py: erd:{name}: {path} does not exist")
        return path
    stems = []
    for dirpath, _, files in os.walk(robots_dir):
        stems += [os.path.join(dirpath, f) for f in files if f == name + ".urdf"]
    if len(stems) != 1:
        sys.exit(f"pin_dynamics.py: erd:{name}: neither an example-robot-data loader with a URDF "
                 f"(known: {sorted(robots_loader.ROBOTS)}) nor the stem of exactly one URDF there "
                 f"({len(stems)} files named {name}.urdf)")
    return stems[0]


# ----------------------------------------------------------------------------------------------
# Command line: global options, then groups that start with --robot.


def usage_error(message: str):
    sys.stderr.write(f"pin_dynamics.py: {message}\n\n")
    sys.stderr.write(__doc__.split("Conventions")[0])
    sys.exit(2)


def parse_args(argv):
    options = {"seed": 0, "states": 20, "out": None, "robots": []}
    i = 0

    def value(flag):
        nonlocal i
        arg = argv[i]
        if arg.startswith(flag + "="):
            return arg[len(flag) + 1 :]
        i += 1
        if i >= len(argv):
            usage_error(f"{flag} needs a value")
        return argv[i]

    while i < len(argv):
        arg = argv[i]
        flag = arg.split("=", 1)[0]
        if flag == "--erd-dir":
            print(erd_robots_dir())
            sys.exit(0)
        elif flag == "--seed":
            options["seed"] = int(value(flag))
        elif flag == "--states":
            options["states"] = int(value(flag))
        elif flag == "--out":
            options["out"] = value(flag)
        elif flag == "--robot":
            options["robots"].append({"spec": value(flag), "name": None, "floating": False, "set": []})
        elif flag in ("--name", "--floating", "--set"):
            if not options["robots"]:
                usage_error(f"{flag} must follow a --robot")
            robot = options["robots"][-1]
            if flag == "--floating":
                robot["floating"] = True
            elif flag == "--name":
                robot["name"] = value(flag)
            else:
                robot["set"].append(value(flag))
        elif flag in ("-h", "--help"):
            print(__doc__)
            sys.exit(0)
        else:
            usage_error(f"unknown argument {arg!r}")
        i += 1
    if options["out"] is None:
        usage_error("--out FILE is required")
    if not options["robots"]:
        usage_error("at least one --robot is required")
    return options


# ----------------------------------------------------------------------------------------------
# --set PATH=VALUE on the URDF text.

LINK_FIELDS = ["mass", "com.x", "com.y", "com.z"] + [f"inertia.{a}" for a in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")]
JOINT_FIELDS = [f"origin.{c}" for c in ("x", "y", "z", "roll", "pitch", "yaw")]


def split_path(path: str):
    """`link.NAME.FIELD` → ("link", NAME, FIELD); NAME may contain dots."""
    kind, _, rest = path.partition(".")
    fields = {"link": LINK_FIELDS, "joint": JOINT_FIELDS}.get(kind)
    if fields is None:
        raise ValueError(f"--set {path}: this script edits link.* and joint.* paths only")
    for field in fields:
        if rest.endswith("." + field) and len(rest) > len(field) + 1:
            return kind, rest[: -len(field) - 1], field
    raise ValueError(f"--set {path}: unknown field; known for {kind}: {', '.join(fields)}")


def vector_attr(element, attr):
    text = element.get(attr, "0 0 0")
    parts = text.split()
    if len(parts) != 3:
        raise ValueError(f"attribute {attr}={text!r} is not three numbers")
    return [float(p) for p in parts]


def apply_set(root, assignment: str):
    """Edits the parsed URDF in place; returns {path, value, urdf_value}."""
    path, sep, raw = assignment.partition("=")
    if not sep:
        raise ValueError(f"--set {assignment}: expected PATH=VALUE")
    value = float(raw)
    kind, name, field = split_path(path)
    matches = [e for e in root.findall(kind) if e.get("name") == name]
    if len(matches) != 1:
        raise ValueError(f"--set {path}: the URDF has {len(matches)} top-level <{kind} name={name!r}>")
    element = matches[0]
    if kind == "link":
        inertial = element.find("inertial")
        if inertial is None:
            raise ValueError(f"--set {path}: link {name!r} has no <inertial>")
        if field == "mass":
            mass = inertial.find("mass")
            old = float(mass.get("value"))
            mass.set("value", repr(value))
        elif field.startswith("com."):
            origin = inertial.find("origin")
            if origin is None:
                origin = ET.SubElement(inertial, "origin", {"xyz": "0 0 0", "rpy": "0 0 0"})
            xyz = vector_attr(origin, "xyz")
            k = "xyz".index(field[-1])
            old, xyz[k] = xyz[k], value
            origin.set("xyz", " ".join(repr(c) for c in xyz))
        else:
            inertia = inertial.find("inertia")
            attr = field.split(".")[1]
            old = float(inertia.get(attr, "0"))
            inertia.set(attr, repr(value))
    else:
        origin = element.find("origin")
        if origin is None:
            origin = ET.SubElement(element, "origin", {"xyz": "0 0 0", "rpy": "0 0 0"})
        component = field.split(".")[1]
        attr, k = ("xyz", "xyz".index(component)) if component in "xyz" else ("rpy", ["roll", "pitch", "yaw"].index(component))
        vec = vector_attr(origin, attr)
        old, vec[k] = vec[k], value
        origin.set(attr, " ".join(repr(c) for c in vec))
    if old == value:
        raise ValueError(f"--set {path}={raw}: equals the URDF value, so it would test nothing")
    return {"path": path, "value": value, "urdf_value": old}


# ----------------------------------------------------------------------------------------------
# One robot.


def joint_kinds(root):
    """URDF joint name → (type, lower, upper) for the top-level <joint> elements."""
    kinds = {}
    for j in root.findall("joint"):
        limit = j.find("limit")
        lower = float(limit.get("lower", "nan")) if limit is not None else math.nan
        upper = float(limit.get("upper", "nan")) if limit is not None else math.nan
        kinds[j.get("name")] = (j.get("type"), lower, upper)
    return kinds


def sample_range(default, lower, upper):
    lo, hi = default
    if math.isfinite(lower) and math.isfinite(upper) and lower < upper:
        lo, hi = max(lo, lower), min(hi, upper)
        if lo >= hi:  # limits entirely outside the default range: use them as they are
            lo, hi = lower, upper
    return lo, hi


def reference_for_robot(index, robot, seed, n_states):
    spec = robot["spec"]
    urdf_path = resolve_erd(spec[4:]) if spec.startswith("erd:") else spec
    label = robot["name"] or (spec[4:] if spec.startswith("erd:") else os.path.splitext(os.path.basename(spec))[0])
    with open(urdf_path, "rb") as f:
        urdf_bytes = f.read()
    root = ET.fromstring(urdf_bytes)
    sets = [apply_set(root, s) for s in robot["set"]]

    if sets:
        xml = ET.tostring(root, encoding="unicode")
        if robot["floating"]:
            model = pin.buildModelFromXML(xml, pin.JointModelFreeFlyer(), "root_joint")
        else:
            model = pin.buildModelFromXML(xml)
    elif robot["floating"]:
        model = pin.buildModelFromUrdf(urdf_path, pin.JointModelFreeFlyer(), "root_joint")
    else:
        model = pin.buildModelFromUrdf(urdf_path)
    model.gravity = pin.Motion(np.array(GRAVITY), np.zeros(3))
    data = model.createData()

    # ribbon-convention layout, in Pinocchio's joint order.
    urdf_joints = joint_kinds(root)
    joints, q_at, v_at = [], 0, 0
    for j in range(1, model.njoints):
        name = model.names[j]
        pin_nq, pin_nv = model.nqs[j], model.nvs[j]
        if name == "root_joint" and robot["floating"]:
            kind, nq, nv = "floating", 7, 6
        else:
            if name not in urdf_joints:
                raise ValueError(f"{label}: Pinocchio joint {name!r} is not a URDF joint")
            kind = urdf_joints[name][0]
            nq, nv = (1, 1) if kind in ("revolute", "continuous", "prismatic") else (None, None)
        if nq is None or pin_nv != nv or (kind == "continuous") != (pin_nq == 2) or (kind != "continuous" and pin_nq != nq):
            raise ValueError(f"{label}: joint {name!r} (URDF type {kind}, Pinocchio {model.joints[j].shortname()} nq={pin_nq} nv={pin_nv}) has no ribbon conversion")
        joints.append({"name": name, "type": kind, "q_index": q_at, "nq": nq, "v_index": v_at, "nv": nv,
                       "pin_q_index": model.idx_qs[j], "pin_nq": pin_nq, "pin_v_index": model.idx_vs[j]})
        q_at, v_at = q_at + nq, v_at + nv
    assert v_at == model.nv

    link_names = [l.get("name") for l in root.findall("link")]
    frame_ids = {}
    for link in link_names:
        if not model.existFrame(link, pin.BODY):
            raise ValueError(f"{label}: Pinocchio has no BODY frame for URDF link {link!r}")
        frame_ids[link] = model.getFrameId(link, pin.BODY)

    rng = np.random.default_rng([seed, index])
    states = []
    for _ in range(n_states):
        q_ribbon = np.zeros(q_at)
        q_pin = np.zeros(model.nq)
        for jt in joints:
            qi, pi = jt["q_index"], jt["pin_q_index"]
            if jt["type"] == "floating":
                xyz = rng.uniform(-1.0, 1.0, 3)
                quat = rng.normal(size=4)
                quat /= np.linalg.norm(quat)
                q_ribbon[qi : qi + 7] = np.concatenate([xyz, quat])
                q_pin[pi : pi + 7] = q_ribbon[qi : qi + 7]
            elif jt["type"] == "continuous":
                theta = rng.uniform(*DEFAULT_ANGLE_RANGE)
                q_ribbon[qi] = theta
                q_pin[pi : pi + 2] = (math.cos(theta), math.sin(theta))
            else:
                _, lower, upper = urdf_joints[jt["name"]]
                default = DEFAULT_ANGLE_RANGE if jt["type"] == "revolute" else DEFAULT_PRISMATIC_RANGE_M
                q_ribbon[qi] = rng.uniform(*sample_range(default, lower, upper))
                q_pin[pi] = q_ribbon[qi]
        # Pinocchio's v ordering is the ribbon-convention v ordering of this layout (same joint order).
        assert all(jt["v_index"] == jt["pin_v_index"] for jt in joints)
        v = rng.normal(size=model.nv)
        tau = rng.normal(size=model.nv)
        qdd = rng.normal(size=model.nv)

        mass = pin.crba(model, data, q_pin)
        mass = np.triu(mass) + np.triu(mass, 1).T
        bias = pin.nonLinearEffects(model, data, q_pin, v).copy()
        aba_qdd = pin.aba(model, data, q_pin, v, tau).copy()
        rnea_tau = pin.rnea(model, data, q_pin, v, qdd).copy()
        pin.framesForwardKinematics(model, data, q_pin)
        frames = {}
        for link, fid in frame_ids.items():
            placement = data.oMf[fid]
            frames[link] = {"position": placement.translation.tolist(), "rotation": placement.rotation.tolist()}
        states.append({
            "q": q_ribbon.tolist(), "v": v.tolist(), "tau": tau.tolist(), "qdd": qdd.tolist(),
            "expected": {"mass_matrix": mass.tolist(), "bias": bias.tolist(), "qdd": aba_qdd.tolist(),
                         "tau": rnea_tau.tolist(), "frames": frames},
        })

    return {
        "name": label,
        "urdf": urdf_path,
        "urdf_fnv1a64": fnv1a64(urdf_bytes),
        "floating": robot["floating"],
        "set": [f"{s['path']}={s['value']!r}" for s in sets],
        "set_applied": sets,
        "nq": q_at,
        "nv": model.nv,
        "joints": joints,
        "links": link_names,
        "states": states,
    }


def to_json(value, depth=0) -> str:
    """Objects indented; a list of lists or objects one compact element per line (a state, a
    joint); a list of numbers on one line. Readable, and a regenerated fixture diffs line by line."""
    pad = " " * (depth + 1)
    if isinstance(value, dict) and value:
        items = [f"{pad}{json.dumps(k)}: {to_json(v, depth + 1)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + " " * depth + "}"
    if isinstance(value, list) and value and isinstance(value[0], (dict, list)):
        if all(isinstance(v, dict) and any(isinstance(x, (dict, list)) and x for x in v.values()) and "states" in v for v in value):
            items = [pad + to_json(v, depth + 1) for v in value]  # robots: indented
        else:
            items = [pad + json.dumps(v, separators=(",", ":")) for v in value]
        return "[\n" + ",\n".join(items) + "\n" + " " * depth + "]"
    return json.dumps(value)


def main(argv):
    options = parse_args(argv)
    robots = []
    for index, robot in enumerate(options["robots"]):
        try:
            robots.append(reference_for_robot(index, robot, options["seed"], options["states"]))
        except (ValueError, OSError, ET.ParseError) as e:
            sys.stderr.write(f"pin_dynamics.py: robot {robot['spec']}: {e}\n")
            sys.exit(1)
    reference = {
        "generator": "tests/reference/pin_dynamics.py",
        "command": ["tests/reference/pin_dynamics.py"] + list(argv),
        "pinocchio_version": pin.__version__,
        "seed": options["seed"],
        "states_per_robot": options["states"],
        "gravity": list(GRAVITY),
        "robots": robots,
    }
    out = options["out"]
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    tmp = out + ".tmp"
    with open(tmp, "w") as f:
        f.write(to_json(reference) + "\n")
    os.replace(tmp, out)


if __name__ == "__main__":
    main(sys.argv[1:])
