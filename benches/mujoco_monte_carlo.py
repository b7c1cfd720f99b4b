#!/usr/bin/env python3
"""Monte Carlo over MuJoCo rollouts on ribbon's d = 3 ur5 study: how many runs, and how much time,
a 1 % envelope costs that way (the headline comparison of benches/ANALYSIS.md).

Usage (from the crate root; the reference JSONs come from `cargo bench --bench analysis_methods`):

    python3 -m venv /work/target-analysis/mujoco-venv
    /work/target-analysis/mujoco-venv/bin/pip install -r benches/requirements.txt
    /work/target-analysis/mujoco-venv/bin/python benches/mujoco_monte_carlo.py \
        [--reference /work/target-analysis/ur5_d3_scan_reference.json] \
        [--fine-reference /work/target-analysis/ur5_d3_scan21_reference.json] \
        [--ribbon /work/target-analysis/analysis_methods.json] \
        [--n 100,400,1600,6400,25600] [--grid 21] [--nthread 0] [--integrator euler] [--seed 0] \
        [--out /work/target-analysis/mujoco_monte_carlo.json]

The study (the same as analysis_methods.rs at d = 3):
- robots/ur5/ur5.urdf with every <visual>/<collision> element removed, loaded by
  mujoco.MjSpec.from_string (URDF compiler defaults: fusestatic merges tool0 into wrist_3_link and
  base_link into the world; no geoms are left, so the URDF inertials are used as they are).
  Contacts and joint limits disabled; gravity (0, 0, -9.81); timestep 1e-3 s; integrator Euler
  (MuJoCo's default: semi-implicit, joint damping implicit) unless --integrator says otherwise.
- The PD hold of robots/ur5/ur5.uncertainty.toml as MuJoCo *joint* stiffness / damping with
  springref = the commanded pose (no actuators): tau = -k (q - springref) - c qdot, the same law as
  ribbon's [[scene.spring]] (k, c per joint as in the sidecar). Armature, frictionloss 0.
- Initial state q = (0, -1.2, 1.0, -0.5, 0, 0), qdot = 0, released at t = 0; 1 s = 1000 steps.
- Parameters, uniform random (numpy default_rng(seed)): payload = wrist_3_link mass in
  [0.15, 1.2] kg (body_mass), its centre of mass z in [-0.002, 0.04] m (body_ipos[2]; x, y stay 0,
  inertia about the COM unchanged: as ribbon's link.wrist_3_link.com.z), and s in [0.95, 1.05]
  multiplying the masses and the inertias of shoulder, upper arm, forearm, wrist 1, wrist 2
  (body_mass, body_inertia; as the sidecar's [bind]).
- Outputs at 100 Hz, t = 0, 0.01, ..., 1: q of the six joints, and tool0's world position (a
  framepos sensor on wrist_3_link's body frame: tool0 coincides with it), as ribbon records them.
- Rollouts: mujoco.rollout.Rollout(nthread=N) over chunks of 100 samples, one MjModel copy per
  sample in the chunk (a pool of copies whose parameters are overwritten per chunk). nthread = 0 runs
  on the calling thread.

Measured: for nested N (the first N of one random sequence) the envelope (min / max over runs) and
its error (docs/method.md section 4: per output max over time of
max(|lo - lo_ref|, |up - up_ref|) / max(w_ref(t), 1e-3 max_t w_ref), then max over outputs; outputs of
zero reference width skipped) against
  (a) ribbon's 11^3 scan reference (MuJoCo's dynamics differ from ribbon's HHT-I3: this error has a
      floor from that model difference),
  (b) MuJoCo's own --grid^3 scan of the same box (its own convergence, without model difference),
  (c) MuJoCo's own largest-N envelope (the brief's self-reference; biased low near the largest N).
The law e(N) = C N^-p is fitted (log-log least squares) to (b) (all N, and N >= 1600; the max and
the mean over time) and to (c) and (a), extrapolated to e = 1 %; the runs times the measured seconds
per run give the time, which is divided by ribbon's legendre-scan k = 4 wall time at d = 3 (from
analysis_methods.json). The measured time of the largest N is compared as well (no extrapolation).
Results and discussion: benches/ANALYSIS.md.
"""

import argparse
import json
import os
import re
import sys
import time

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

HERE = os.path.dirname(os.path.abspath(__file__))
URDF = os.path.join(HERE, "..", "robots", "ur5", "ur5.urdf")
TIMESTEP = 1e-3
NSTEP = 1000
RECORD_EVERY = 10
CHUNK = 100

JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
          "wrist_2_joint", "wrist_3_joint"]
# (stiffness N·m/rad, damping N·m·s/rad, rest rad), robots/ur5/ur5.uncertainty.toml [[scene.spring]]
SPRINGS = [(3000.0, 60.0, 0.0), (3000.0, 60.0, -1.2), (2000.0, 40.0, 1.0), (300.0, 3.0, -0.5),
           (300.0, 3.0, 0.0), (300.0, 3.0, 0.0)]
Q0 = [0.0, -1.2, 1.0, -0.5, 0.0, 0.0]
PAYLOAD_MASS = (0.15, 1.2)
PAYLOAD_COM_Z = (-0.002, 0.04)
SCALE = (0.95, 1.05)
SCALED_LINKS = ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link"]
OUTPUTS = [f"q.{j}" for j in JOINTS] + ["frame.tool0.x", "frame.tool0.y", "frame.tool0.z"]
INTEGRATORS = {"euler": mujoco.mjtIntegrator.mjINT_EULER,
               "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
               "rk4": mujoco.mjtIntegrator.mjINT_RK4}


def strip_geometry(text):
    for tag in ("visual", "collision"):
        text = re.sub(rf"<{tag}\b[^>]*/>", "", text)
        text = re.sub(rf"<{tag}\b.*?</{tag}>", "", text, flags=re.S)
    return text


def build_model(integrator):
    with open(URDF) as f:
        spec = mujoco.MjSpec.from_string(strip_geometry(f.read()))
    joints = {j.name: j for j in spec.joints}
    for name, (k, c, rest) in zip(JOINTS, SPRINGS):
        j = joints[name]
        j.stiffness = [k, 0.0, 0.0]  # MuJoCo 4: polynomial stiffness, linear term first
        j.damping = [c, 0.0, 0.0]
        j.springref = rest
        j.armature = 0.0
        j.frictionloss = 0.0
    sensor = spec.add_sensor()
    sensor.name = "tool0"
    sensor.type = mujoco.mjtSensor.mjSENS_FRAMEPOS
    sensor.objtype = mujoco.mjtObj.mjOBJ_XBODY  # the body frame (not the inertial frame)
    sensor.objname = "wrist_3_link"
    model = spec.compile()
    model.opt.timestep = TIMESTEP
    model.opt.gravity[:] = (0.0, 0.0, -9.81)
    model.opt.integrator = INTEGRATORS[integrator]
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_LIMIT)
    assert [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)] == JOINTS
    assert np.allclose(model.jnt_stiffness, [s[0] for s in SPRINGS])
    assert np.allclose(model.dof_damping, [s[1] for s in SPRINGS])
    assert np.allclose(model.qpos_spring, [s[2] for s in SPRINGS])
    return model


class Runner:
    """Rolls out parameter points (rows: payload mass, payload com z, s) in chunks of CHUNK."""

    def __init__(self, model, nthread):
        self.base = model
        self.body = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b): b for b in range(model.nbody)}
        self.w3 = self.body["wrist_3_link"]
        self.scaled = [self.body[n] for n in SCALED_LINKS]
        self.mass0 = model.body_mass.copy()
        self.inertia0 = model.body_inertia.copy()
        self.models = [_copy(model) for _ in range(CHUNK)]
        self.nthread = nthread
        self.datas = [mujoco.MjData(model) for _ in range(max(nthread, 1))]
        data = mujoco.MjData(model)
        data.qpos[:] = Q0
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)
        self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.nstate = mujoco.mj_stateSize(model, self.spec)
        init = np.empty(self.nstate)
        mujoco.mj_getState(model, data, init, self.spec)
        self.initial = np.tile(init, (CHUNK, 1))
        self.tool0_at_0 = data.sensordata[:3].copy()
        self.control = np.zeros((CHUNK, NSTEP, 0))
        self.state = np.empty((CHUNK, NSTEP, self.nstate))
        self.sensordata = np.empty((CHUNK, NSTEP, model.nsensordata))
        self.pool = mj_rollout.Rollout(nthread=nthread)
        self.rollout_seconds = 0.0
        self.sensor_lag = None

    def apply(self, model, x):
        mass, com_z, s = x
        model.body_mass[:] = self.mass0
        model.body_inertia[:] = self.inertia0
        for b in self.scaled:
            model.body_mass[b] = s * self.mass0[b]
            model.body_inertia[b] = s * self.inertia0[b]
        model.body_mass[self.w3] = mass
        model.body_ipos[self.w3] = (0.0, 0.0, com_z)

    def run(self, points):
        """Outputs (n, 9, 101) for n ≤ CHUNK points."""
        n = len(points)
        for model, x in zip(self.models, points):
            self.apply(model, x)
        start = time.perf_counter()
        self.pool.rollout(self.models[:n], self.datas, self.initial[:n], self.control[:n],
                          nstep=NSTEP, state=self.state[:n], sensordata=self.sensordata[:n],
                          skip_checks=True)
        self.rollout_seconds += time.perf_counter() - start
        if self.sensor_lag is None:
            self.sensor_lag = self.check_sensor_alignment(self.models[0])
        out = np.empty((n, len(OUTPUTS), NSTEP // RECORD_EVERY + 1))
        # state[:, i] is the state after step i + 1 (time (i + 1) h); FULLPHYSICS = time, qpos, ...
        idx = np.arange(RECORD_EVERY - 1, NSTEP, RECORD_EVERY)
        out[:, :6, 0] = Q0
        out[:, :6, 1:] = self.state[:n, idx, 1:7].transpose(0, 2, 1)
        out[:, 6:, 0] = self.tool0_at_0
        # sensor_lag = 1: sensordata[:, i] is evaluated at the state before step i + 1, i.e. the
        # position at time (i + 1) h is sensordata[:, i + 1] (the last one then needs one more
        # evaluation, done below with mj_kinematics per run).
        if self.sensor_lag == 0:
            out[:, 6:, 1:] = self.sensordata[:n, idx, :3].transpose(0, 2, 1)
        else:
            out[:, 6:, 1:-1] = self.sensordata[:n, idx[:-1] + 1, :3].transpose(0, 2, 1)
            data = self.datas[0]
            for r in range(n):
                data.qpos[:] = self.state[r, -1, 1:7]
                mujoco.mj_kinematics(self.models[r], data)
                out[r, 6:, -1] = data.xpos[self.w3]
        return out

    def check_sensor_alignment(self, model):
        """Which step's state the sensor reading at rollout index i belongs to (0: after step i+1)."""
        data = mujoco.MjData(model)
        for i in (10, 500):
            data.qpos[:] = self.state[0, i, 1:7]
            mujoco.mj_kinematics(model, data)
            after = data.xpos[self.w3].copy()
            if np.allclose(self.sensordata[0, i, :3], after, atol=1e-12, rtol=0):
                continue
            data.qpos[:] = self.state[0, i - 1, 1:7]
            mujoco.mj_kinematics(model, data)
            if np.allclose(self.sensordata[0, i, :3], data.xpos[self.w3], atol=1e-12, rtol=0):
                return 1
            sys.exit("mujoco_monte_carlo.py: cannot align the tool0 sensor with the rollout states")
        return 0


def _copy(model):
    import copy
    return copy.copy(model)


def envelope_error(lo, up, lo_ref, up_ref, first=0):
    """docs/method.md section 4, per output: returns (max over outputs of max_t e, max over outputs of
    mean_t e, worst output index, per-output max). Zero-width references are skipped. `first` > 0
    restricts max and mean to record times from index `first` on (the width floor still uses every
    time)."""
    worst, emax, emean, per = -1, 0.0, 0.0, []
    for o in range(lo_ref.shape[0]):
        w = up_ref[o] - lo_ref[o]
        wmax = w.max()
        if wmax <= 1e-12:
            per.append(None)
            continue
        dev = np.maximum(np.abs(lo[o] - lo_ref[o]), np.abs(up[o] - up_ref[o]))
        e = (dev / np.maximum(w, 1e-3 * wmax))[first:]
        per.append(float(e.max()))
        if e.max() > emax:
            emax, worst = float(e.max()), o
        emean = max(emean, float(e.mean()))
    return emax, emean, worst, per


def load_reference(path):
    with open(path) as f:
        doc = json.load(f)
    env = doc["envelope"]
    names = [o["name"] for o in env["outputs"]]
    assert names == OUTPUTS, f"{path}: outputs {names} != {OUTPUTS}"
    lo = np.array([o["lower"] for o in env["outputs"]])
    up = np.array([o["upper"] for o in env["outputs"]])
    nominal = np.array([o.get("nominal", [np.nan] * len(env["time"])) for o in env["outputs"]])
    assert len(env["time"]) == NSTEP // RECORD_EVERY + 1
    return doc, lo, up, nominal


def fit_law(ns, es):
    x, y = np.log(np.asarray(ns, float)), np.log(np.asarray(es, float))
    p, logc = np.polyfit(x, y, 1)
    return float(np.exp(logc)), float(-p)


def main():
    default_dir = os.environ.get("CARGO_TARGET_DIR", "/work/target-analysis")
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reference", default=os.path.join(default_dir, "ur5_d3_scan_reference.json"))
    ap.add_argument("--fine-reference", default=os.path.join(default_dir, "ur5_d3_scan21_reference.json"))
    ap.add_argument("--ribbon", default=os.path.join(default_dir, "analysis_methods.json"))
    ap.add_argument("--n", default="100,400,1600,6400,25600")
    ap.add_argument("--grid", type=int, default=21, help="points per dimension of MuJoCo's own scan")
    ap.add_argument("--nthread", type=int, default=0)
    ap.add_argument("--integrator", default="euler", choices=sorted(INTEGRATORS))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=os.path.join(default_dir, "mujoco_monte_carlo.json"))
    args = ap.parse_args()
    ns = sorted(int(n) for n in args.n.split(","))
    assert all(n % CHUNK == 0 for n in ns), f"every N must be a multiple of {CHUNK}"

    ref_doc, lo_ref, up_ref, ribbon_nominal = load_reference(args.reference)
    names = [x["name"] for x in ref_doc["parameters"]]
    assert names == ["link.wrist_3_link.mass", "link.wrist_3_link.com.z", "s"], names
    assert np.allclose([[x["lower"], x["upper"]] for x in ref_doc["parameters"]],
                       [PAYLOAD_MASS, PAYLOAD_COM_Z, SCALE])
    # ribbon's nominal run: a direct path at its URDF value, a symbol at its midpoint.
    nominal_point = np.array([x["nominal"] for x in ref_doc["parameters"]])
    fine = None
    if os.path.exists(args.fine_reference):
        _, lo_fine, up_fine, _ = load_reference(args.fine_reference)
        fine = (lo_fine, up_fine)
    model = build_model(args.integrator)
    runner = Runner(model, args.nthread)
    result = {"mujoco": mujoco.__version__, "integrator": args.integrator, "nthread": args.nthread,
              "timestep": TIMESTEP, "nstep": NSTEP, "chunk": CHUNK, "seed": args.seed,
              "loadavg_start": open("/proc/loadavg").read().split()[:3]}

    # Model difference at ribbon's nominal point (payload 0.1879 kg, com z -0.001159 m, s = 1).
    nominal_out = runner.run(nominal_point[None, :])[0]
    diff = np.abs(nominal_out - ribbon_nominal)
    widths = (up_ref - lo_ref).max(axis=1)
    result["nominal_point"] = nominal_point.tolist()
    result["nominal_vs_ribbon"] = {
        name: {"max_abs_diff": float(diff[o].max()), "ref_max_width": float(widths[o]),
               "diff_over_width": float(diff[o].max() / widths[o]) if widths[o] > 0 else None}
        for o, name in enumerate(OUTPUTS)}
    print(f"# MuJoCo {mujoco.__version__}, integrator {args.integrator}, nthread {args.nthread}; "
          f"tool0 sensor lag {runner.sensor_lag}; loadavg {result['loadavg_start']}")
    print("# nominal run, MuJoCo vs ribbon: max |difference| over time, and over the 11^3 reference's max width")
    for name, v in result["nominal_vs_ribbon"].items():
        print(f"#   {name:<22} {v['max_abs_diff']:.3e}  ({100 * (v['diff_over_width'] or 0):.1f} % of width {v['ref_max_width']:.3e})")

    # MuJoCo's own grid scan: its converged envelope.
    g = np.linspace(-1.0, 1.0, args.grid)
    bounds = np.array([PAYLOAD_MASS, PAYLOAD_COM_Z, SCALE])
    xi = np.array(np.meshgrid(g, g, g, indexing="ij")).reshape(3, -1).T
    grid_points = bounds.mean(axis=1) + xi * (bounds[:, 1] - bounds[:, 0]) / 2
    runner.rollout_seconds = 0.0
    start = time.perf_counter()
    glo = np.full((len(OUTPUTS), NSTEP // RECORD_EVERY + 1), np.inf)
    gup = -glo
    for c in range(0, len(grid_points), CHUNK):
        out = runner.run(grid_points[c:c + CHUNK])
        glo = np.minimum(glo, out.min(axis=0))
        gup = np.maximum(gup, out.max(axis=0))
    glo, gup = np.minimum(glo, nominal_out), np.maximum(gup, nominal_out)
    grid_wall = time.perf_counter() - start
    e_grid_ribbon = envelope_error(glo, gup, lo_ref, up_ref)
    e_grid_ribbon10 = envelope_error(glo, gup, lo_ref, up_ref, first=10)
    result["grid"] = {"points": int(len(grid_points)), "wall_s": grid_wall,
                      "rollout_s": runner.rollout_seconds,
                      "error_vs_ribbon_ref": {"max": e_grid_ribbon[0], "mean": e_grid_ribbon[1],
                                              "worst": OUTPUTS[e_grid_ribbon[2]], "per_output": e_grid_ribbon[3]},
                      "error_vs_ribbon_ref_from_0.1s": {"max": e_grid_ribbon10[0], "mean": e_grid_ribbon10[1],
                                                        "worst": OUTPUTS[e_grid_ribbon10[2]]}}
    print(f"# MuJoCo {args.grid}^3 scan: {len(grid_points)} runs in {grid_wall:.2f} s "
          f"(rollout {runner.rollout_seconds:.2f} s); vs ribbon 11^3 reference: "
          f"max {100 * e_grid_ribbon[0]:.2f} % (worst {OUTPUTS[e_grid_ribbon[2]]}), mean {100 * e_grid_ribbon[1]:.2f} %; "
          f"from t = 0.1 s on: max {100 * e_grid_ribbon10[0]:.2f} % (worst {OUTPUTS[e_grid_ribbon10[2]]})")

    # Monte Carlo, nested N.
    rng = np.random.default_rng(args.seed)
    nmax = ns[-1]
    points = bounds[:, 0] + rng.random((nmax, 3)) * (bounds[:, 1] - bounds[:, 0])
    lo = nominal_out.copy()
    up = nominal_out.copy()
    snapshots = {}
    runner.rollout_seconds = 0.0
    start = time.perf_counter()
    for c in range(0, nmax, CHUNK):
        out = runner.run(points[c:c + CHUNK])
        lo = np.minimum(lo, out.min(axis=0))
        up = np.maximum(up, out.max(axis=0))
        if c + CHUNK in ns:
            snapshots[c + CHUNK] = (lo.copy(), up.copy(), time.perf_counter() - start, runner.rollout_seconds)
    mc_wall = time.perf_counter() - start
    seconds_per_run = mc_wall / nmax
    rollout_per_run = runner.rollout_seconds / nmax
    rows = []
    print()
    print("| N | wall s | err vs ribbon 11^3 max % | mean % | same, t ≥ 0.1 s, max % | err vs ribbon 21^3 max % | "
          f"err vs MuJoCo {args.grid}^3 max % | mean % | worst output | err vs MuJoCo N={nmax} max % |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    for n in ns:
        slo, sup, wall, _ = snapshots[n]
        ea = envelope_error(slo, sup, lo_ref, up_ref)
        ea10 = envelope_error(slo, sup, lo_ref, up_ref, first=10)
        eb = envelope_error(slo, sup, glo, gup)
        ec = envelope_error(slo, sup, lo, up)
        ef = envelope_error(slo, sup, *fine) if fine else (float("nan"),) * 3
        rows.append({"n": n, "wall_s": wall,
                     "vs_ribbon_11": {"max": ea[0], "mean": ea[1], "worst": OUTPUTS[ea[2]]},
                     "vs_ribbon_11_from_0.1s": {"max": ea10[0], "mean": ea10[1], "worst": OUTPUTS[ea10[2]]},
                     "vs_ribbon_21": {"max": ef[0]} if fine else None,
                     "vs_mujoco_grid": {"max": eb[0], "mean": eb[1], "worst": OUTPUTS[eb[2]] if eb[2] >= 0 else None,
                                        "per_output": eb[3]},
                     "vs_mujoco_largest_n": {"max": ec[0], "mean": ec[1]}})
        print(f"| {n} | {wall:.2f} | {100 * ea[0]:.2f} | {100 * ea[1]:.2f} | {100 * ea10[0]:.2f} | {100 * ef[0]:.2f} | "
              f"{100 * eb[0]:.2f} | {100 * eb[1]:.2f} | {OUTPUTS[eb[2]]} | {100 * ec[0]:.2f} |")
    result["monte_carlo"] = rows
    result["seconds_per_run"] = seconds_per_run
    result["rollout_seconds_per_run"] = rollout_per_run
    print(f"# {nmax} runs in {mc_wall:.2f} s: {1e3 * seconds_per_run:.3f} ms per run "
          f"({1e3 * rollout_per_run:.3f} ms in rollout, {1e6 * rollout_per_run / NSTEP:.2f} µs per step)")

    # The law, against MuJoCo's own scan (no model difference); also the largest-N self-reference
    # (leaving out the largest N, whose error is 0 by construction).
    laws = {}
    tail = [n for n in ns if n >= 1600]
    for label, key, stat, sel in [("vs_mujoco_grid", "vs_mujoco_grid", "max", ns),
                                  ("vs_mujoco_grid_N>=1600", "vs_mujoco_grid", "max", tail),
                                  ("vs_mujoco_grid_mean", "vs_mujoco_grid", "mean", ns),
                                  ("vs_mujoco_largest_n", "vs_mujoco_largest_n", "max", ns[:-1]),
                                  ("vs_ribbon_11", "vs_ribbon_11", "max", ns)]:
        es = [r[key][stat] for r in rows if r["n"] in sel]
        if len(sel) >= 2 and all(e > 0 for e in es):
            c_, p_ = fit_law(sel, es)
            n1 = (c_ / 0.01) ** (1.0 / p_) if p_ > 0 else float("inf")
            laws[label] = {"error": stat, "fitted_n": sel, "C": c_, "p": p_, "runs_for_1pct": n1,
                           "seconds_for_1pct": n1 * seconds_per_run}
    result["laws"] = laws
    print()
    for key, law in laws.items():
        print(f"# law {key} ({law['error']} over time, N = {law['fitted_n'][0]}..{law['fitted_n'][-1]}): "
              f"e(N) = {law['C']:.3g} N^-{law['p']:.3f}; 1 % at N = {law['runs_for_1pct']:.3g} runs "
              f"= {law['seconds_for_1pct']:.4g} s at {1e3 * seconds_per_run:.3f} ms per run")

    if os.path.exists(args.ribbon):
        with open(args.ribbon) as f:
            ribbon = json.load(f)
        ls = [r for r in ribbon["rows"] if r["d"] == 3 and r["method"] == "legendre-scan" and r.get("order") == 4]
        if ls:
            r = ls[0]
            result["ribbon_legendre_scan_k4_d3"] = {"runs": r["runs"], "wall_s": r["wall_s"],
                                                    "error_max": r["error_max"], "threads": r["threads"]}
            print(f"# ribbon legendre-scan k=4, d = 3: {r['runs']} runs, {r['wall_s']:.3f} s on {r['threads']} threads, "
                  f"error {100 * r['error_max']:.3f} % (max) vs its 11^3 scan")
            result["speedup_for_1pct"] = {}
            for key, law in laws.items():
                if key.startswith("vs_ribbon"):
                    continue
                speedup = law["seconds_for_1pct"] / r["wall_s"]
                result["speedup_for_1pct"][key] = speedup
                print(f"#   MuJoCo Monte Carlo to 1 % by law {key}: {law['runs_for_1pct']:.3g} runs, "
                      f"{law['seconds_for_1pct']:.4g} s on nthread={args.nthread}: {speedup:.3g}x ribbon's time")
            measured = nmax * seconds_per_run / r["wall_s"]
            result["speedup_measured_largest_n"] = measured
            print(f"#   measured: MuJoCo's {nmax} runs took {nmax * seconds_per_run:.4g} s = {measured:.3g}x ribbon's time "
                  f"and were still {100 * rows[-1]['vs_mujoco_grid']['max']:.2f} % (max) off MuJoCo's own {args.grid}^3 scan")
    result["loadavg_end"] = open("/proc/loadavg").read().split()[:3]
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)
    print(f"# wrote {args.out}; loadavg {result['loadavg_end']}")


if __name__ == "__main__":
    main()
