#!/usr/bin/env python3
"""MuJoCo's step timed on the robots of benches/hht_step.rs: the reference for ribbon's HHT step.

Usage (from the crate root, in a venv made from benches/requirements.txt):

    python3 -m venv /work/target-bench/mujoco-venv
    /work/target-bench/mujoco-venv/bin/pip install -r benches/requirements.txt
    /work/target-bench/mujoco-venv/bin/python benches/mujoco_timing.py [--nstep N] [--number K]
        [--repeat R] [--reference-venv DIR] [URDF ...]

Without URDFs it times robots/ur5/ur5.urdf, example-robot-data's ur5 and panda, found in the
reference venv's cmeel.prefix (default target/reference-venv, the venv `cargo test --release` makes;
a robot whose URDF is missing is skipped with a line on stderr), robots/quadruped (floating base) and
robots/four_bar (a loop). Prints JSON on stdout.

What is simulated (the same problem as benches/hht_step.rs):
- The URDF with every <visual> and <collision> element removed (MuJoCo cannot resolve `package://`
  meshes, and only inertials and joints matter here), loaded with mujoco.MjSpec.from_string and
  MuJoCo's URDF compiler defaults, which the JSON reports: discardvisual = true, fusestatic = true (fixed
  children merged into their parent, as ribbon does), balanceinertia = false, inertiafromgeom = auto
  (no geoms are left, so the URDF inertials are used as they are), autolimits = true.
- Gravity (0, 0, -9.81), timestep 1e-3 s, one thread (rollout with nthread = 0 runs on the calling
  thread).
- Contacts and joint limits disabled (opt.disableflags |= CONTACT | LIMIT): ribbon's gravity-only
  scene has neither. URDF mimic joints become MuJoCo joint equalities (the panda's finger); ribbon's
  scene has them as a constraint row too, so they stay on. The "no equality" variant also disables
  them (timing only the unconstrained dynamics).
- Joint damping, armature and frictionloss: the values MuJoCo's URDF import gives are reported
  (`loaded_joint_terms`), then all set to 0, as ribbon's gravity-only scene applies none (panda's
  URDF declares damping 0.003 and 0.3; nonzero damping also adds work to MuJoCo's Euler step).
- Start: q0 = REVOLUTE_Q0 cycled over the hinge joints in order, prismatic joints at 0.02 m, v0 = 0
  (the same state as benches/hht_step.rs), a 1 s passive fall of `nstep` = 1000 steps.
- quadruped.urdf (benches/support/fall.rs): its root body gets a free joint (MuJoCo's URDF import
  fixes the root; ribbon's `base = "floating"`), starting at QUADRUPED_BASE_XYZ, identity
  orientation, angular velocity QUADRUPED_BASE_W (body frame, MuJoCo's convention for a free joint's
  angular velocity as for ribbon's; linear velocity 0), hinges at REVOLUTE_Q0; no ground.
- four_bar.urdf: the scene of its shipped sidecar (four_bar.uncertainty.toml, read here): its
  gravity, initial.q and initial.v by joint name, and its loop as a `connect` equality between two
  sites at the origins of the frames the sidecar's planar pin joins (3 rows in MuJoCo, whose third
  is identically satisfied in the plane; 2 rows in ribbon). MuJoCo refuses its bars' zero inertia
  about their own axis: compiler.boundinertia = 1e-9 kg m^2 (no joint turns about that axis).

Method: `mujoco.rollout.Rollout(nthread=0).rollout(..., skip_checks=True)` with preallocated
outputs, which runs the whole trajectory in C (mj_step per step, plus copying the state out).
Each timing is the minimum over R runs of K rollouts (timeit-style, so that another process on the
machine inflates nothing). The per-call Python overhead is removed by also timing 1-step rollouts:
µs per step = (t(nstep) - t(1)) / (nstep - 1). Integrators: Euler (MuJoCo's default), RK4 and
implicitfast. Not timed, for accuracy context: the same fall with RK4 at timestep / 10, whose end
positions (`reference_qpos_at_end`) each variant's `max_abs_error_at_end_vs_reference` is measured
against (ribbon's HHT end positions are printed by benches/hht_step.rs for the same comparison).
"""

import glob
import json
import os
import re
import sys
import time
import tomllib

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

REVOLUTE_Q0 = [0.3, -0.8, 0.5, -1.2, 0.4, 1.0, 0.7]  # keep in sync with benches/hht_step.rs
PRISMATIC_Q0 = 0.02
TIMESTEP = 1e-3
QUADRUPED_BASE_XYZ = [0.0, 0.0, 0.461]  # keep in sync with benches/support/fall.rs
QUADRUPED_BASE_W = [0.4, -0.3, 0.2]
FOUR_BAR_INERTIA_FLOOR = 1e-9  # kg m^2

# Inside the reference venv, under whichever Python 3 made it.
ERD_GLOB = "lib/python3*/site-packages/cmeel.prefix/share/example-robot-data/robots"
ERD_ROBOTS = [
    ("erd-ur5", "ur_description/urdf/ur5_robot.urdf"),
    ("erd-panda", "panda_description/urdf/panda.urdf"),
]


def strip_geometry(urdf_text):
    """Removes every <visual> and <collision> element (and self-closing ones)."""
    for tag in ("visual", "collision"):
        urdf_text = re.sub(rf"<{tag}\b[^>]*/>", "", urdf_text)
        urdf_text = re.sub(rf"<{tag}\b.*?</{tag}>", "", urdf_text, flags=re.S)
    return urdf_text


def robot_kind(path):
    """'quadruped', 'four_bar' or 'arm' (the problem benches/support/fall.rs gives ribbon)."""
    return {"quadruped.urdf": "quadruped", "four_bar.urdf": "four_bar"}.get(
        os.path.basename(path), "arm")


def four_bar_scene(path):
    """The shipped four-bar sidecar's [scene] and its single [[scene.loop]]."""
    with open(os.path.join(os.path.dirname(path), "four_bar.uncertainty.toml"), "rb") as f:
        scene = tomllib.load(f)["scene"]
    (pin,) = scene["loop"]
    if pin["type"] != "planar_pin" or any(pin["point_in_parent"]) or any(pin["point_in_child"]):
        sys.exit("mujoco_timing.py: the four-bar's loop is no longer a planar pin at two frame "
                 "origins; update four_bar_scene")
    return scene, pin


def load(path, integrator, equality):
    with open(path) as f:
        spec = mujoco.MjSpec.from_string(strip_geometry(f.read()))
    gravity = (0.0, 0.0, -9.81)
    if robot_kind(path) == "quadruped":
        spec.worldbody.first_body().add_freejoint()
    elif robot_kind(path) == "four_bar":
        scene, pin = four_bar_scene(path)
        gravity = tuple(scene["gravity"])
        # Its slender bars have no inertia about their own axis (x), which MuJoCo refuses; no joint
        # turns about x, so a floor of 1e-9 kg m^2 changes nothing of the planar motion.
        spec.compiler.boundinertia = FOUR_BAR_INERTIA_FLOOR
        for frame in (pin["parent"], pin["child"]):
            spec.body(frame).add_site(name=frame, pos=[0.0, 0.0, 0.0])
        spec.add_equality(type=mujoco.mjtEq.mjEQ_CONNECT, objtype=mujoco.mjtObj.mjOBJ_SITE,
                          name1=pin["parent"], name2=pin["child"])
    compiler = {
        "discardvisual": bool(spec.compiler.discardvisual),
        "fusestatic": bool(spec.compiler.fusestatic),
        "balanceinertia": bool(spec.compiler.balanceinertia),
        "inertiafromgeom": str(spec.compiler.inertiafromgeom),
        "autolimits": bool(spec.compiler.autolimits),
    }
    model = spec.compile()
    loaded = {
        "damping": model.dof_damping.tolist(),
        "armature": model.dof_armature.tolist(),
        "frictionloss": model.dof_frictionloss.tolist(),
        "limited": [bool(x) for x in model.jnt_limited],
    }
    model.dof_damping[:] = 0.0
    model.dof_armature[:] = 0.0
    model.dof_frictionloss[:] = 0.0
    model.opt.timestep = TIMESTEP
    model.opt.gravity[:] = gravity
    model.opt.integrator = integrator
    flags = mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_LIMIT
    if not equality:
        flags |= mujoco.mjtDisableBit.mjDSBL_EQUALITY
    model.opt.disableflags |= int(flags)
    return model, compiler, loaded


def initial_state(model, path):
    """(qpos, qvel) at the start of the bench problem (module docstring)."""
    q = np.zeros(model.nq)
    v = np.zeros(model.nv)
    if robot_kind(path) == "four_bar":
        scene, _ = four_bar_scene(path)
        for key, values in (("q", q), ("v", v)):
            for name, value in scene["initial"][key].items():
                joint = model.joint(name)
                values[joint.qposadr[0] if key == "q" else joint.dofadr[0]] = value
        return q, v
    hinge = 0
    for j in range(model.njnt):
        adr = model.jnt_qposadr[j]
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            q[adr] = REVOLUTE_Q0[hinge % len(REVOLUTE_Q0)]
            hinge += 1
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            q[adr] = PRISMATIC_Q0
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            q[adr:adr + 3] = QUADRUPED_BASE_XYZ
            q[adr + 3:adr + 7] = (1.0, 0.0, 0.0, 0.0)
            dof = model.jnt_dofadr[j]
            v[dof + 3:dof + 6] = QUADRUPED_BASE_W
        else:
            sys.exit(f"mujoco_timing.py: joint type {model.jnt_type[j]} not handled")
    return q, v


def time_rollout(model, path, nstep, number, repeat):
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_state(model, path)
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    nstate = mujoco.mj_stateSize(model, spec)
    initial = np.empty((1, nstate))
    mujoco.mj_getState(model, data, initial[0], spec)
    control = np.zeros((1, nstep, mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_CTRL)))
    outputs = {n: (np.empty((1, n, nstate)), np.empty((1, n, model.nsensordata))) for n in (1, nstep)}

    with mj_rollout.Rollout(nthread=0) as runner:

        def run(n):
            state, sensordata = outputs[n]
            runner.rollout([model], [data], initial, control[:, :n, :], skip_checks=True,
                           nstep=n, state=state, sensordata=sensordata)

        def best(n):
            runs = []
            for _ in range(repeat):
                start = time.perf_counter()
                for _ in range(number):
                    run(n)
                runs.append((time.perf_counter() - start) / number)
            return min(runs)

        run(nstep)  # warm up
        t_full = best(nstep)
        t_one = best(1)
        final_qpos = outputs[nstep][0][0, -1, 1:1 + model.nq]  # FULLPHYSICS: time, qpos, qvel, ...
    return {
        "us_per_step": (t_full - t_one) / (nstep - 1) * 1e6,
        "rollout_us": t_full * 1e6,
        "one_step_rollout_us": t_one * 1e6,
        "qpos_at_end": [round(float(x), 6) for x in final_qpos],
        "_qpos_at_end": final_qpos.copy(),
    }


def time_robot(label, path, nstep, number, repeat):
    variants = {}
    compiler = loaded = None
    base = None
    for name, integrator, equality in [
        ("euler", mujoco.mjtIntegrator.mjINT_EULER, True),
        ("rk4", mujoco.mjtIntegrator.mjINT_RK4, True),
        ("implicitfast", mujoco.mjtIntegrator.mjINT_IMPLICITFAST, True),
        ("euler_no_equality", mujoco.mjtIntegrator.mjINT_EULER, False),
    ]:
        model, compiler, loaded = load(path, integrator, equality)
        if base is None:
            base = model
        if name == "euler_no_equality" and model.neq == 0:
            continue
        variants[name] = time_rollout(model, path, nstep, number, repeat)
    names = [mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(base.njnt)]
    # Accuracy context (not timed): the same fall with RK4 at a 10x smaller step, as a reference
    # for the end positions of every variant above and of ribbon's HHT (printed by hht_step.rs).
    model, _, _ = load(path, mujoco.mjtIntegrator.mjINT_RK4, True)
    model.opt.timestep = TIMESTEP / 10
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_state(model, path)
    for _ in range(10 * nstep):
        mujoco.mj_step(model, data)
    reference = data.qpos.copy()
    for result in variants.values():
        result["max_abs_error_at_end_vs_reference"] = float(
            np.max(np.abs(result.pop("_qpos_at_end") - reference)))
    return {
        "robot": label,
        "urdf": path,
        "nq": base.nq,
        "nv": base.nv,
        "nbody": base.nbody,
        "neq": base.neq,
        "joints": names,
        "q0": initial_state(base, path)[0].tolist(),
        "v0": initial_state(base, path)[1].tolist(),
        "compiler": compiler,
        "loaded_joint_terms": loaded,
        "set_joint_terms": "damping, armature and frictionloss set to 0",
        "reference_qpos_at_end": {"integrator": "rk4", "timestep": TIMESTEP / 10,
                                  "qpos": [round(float(x), 6) for x in reference]},
        "results": variants,
    }


def main(argv):
    nstep, number, repeat, venv, urdfs = 1000, 5, 7, "target/reference-venv", []
    i = 0
    while i < len(argv):
        flag, _, inline = argv[i].partition("=")
        if flag in ("--nstep", "--number", "--repeat", "--reference-venv"):
            if not inline:
                i += 1
                inline = argv[i]
            if flag == "--nstep":
                nstep = int(inline)
            elif flag == "--number":
                number = int(inline)
            elif flag == "--repeat":
                repeat = int(inline)
            else:
                venv = inline
        elif flag in ("-h", "--help"):
            print(__doc__)
            return
        else:
            urdfs.append((os.path.splitext(os.path.basename(argv[i]))[0], argv[i]))
        i += 1
    if nstep < 2:
        sys.exit("mujoco_timing.py: --nstep must be at least 2")
    if not urdfs:
        urdfs.append(("ribbon-ur5", "robots/ur5/ur5.urdf"))
        for label, relative in ERD_ROBOTS:
            found = sorted(glob.glob(os.path.join(venv, ERD_GLOB)))
            path = os.path.join(found[-1] if found else os.path.join(venv, ERD_GLOB), relative)
            if os.path.isfile(path):
                urdfs.append((label, path))
            else:
                print(f"{label}: skipped, {path} not found (run `cargo test --release` once to "
                      "create the reference venv)", file=sys.stderr)
        urdfs.append(("ribbon-quadruped", "robots/quadruped/quadruped.urdf"))
        urdfs.append(("ribbon-four-bar", "robots/four_bar/four_bar.urdf"))
    results = [time_robot(label, path, nstep, number, repeat) for label, path in urdfs]
    print(json.dumps({
        "mujoco_version": mujoco.__version__,
        "method": f"rollout(nthread=0) of {nstep} steps, min of {repeat} runs of {number} rollouts; "
                  f"us_per_step = (t({nstep}) - t(1)) / {nstep - 1}",
        "timestep": TIMESTEP,
        "disabled": "contact, limit (and equality in euler_no_equality)",
        "results": results,
    }, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
