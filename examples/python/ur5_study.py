#!/usr/bin/env python3
"""The ur5 study from Python: bound envelopes of its joint motion plotted with matplotlib, and its
nominal dynamics compared with Pinocchio along the nominal trajectory.

    pip install ./python matplotlib pin         # once (pin is Pinocchio's PyPI package)
    python examples/python/ur5_study.py --out target/ur5-python

Writes OUT/ur5_envelopes.png (one panel per joint: the envelope as a band, the nominal run as a
line) and OUT/ur5.mcap (for Foxglove or rerun), and prints the check's verdict, the most
important parameters and the largest difference from Pinocchio.
"""

import argparse
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import ribbon  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
URDF = str(ROOT / "robots" / "ur5" / "ur5.urdf")
# Two double-precision implementations of the same recursions agree to round-off: relative to the
# largest entry of each quantity, far below this.
PINOCCHIO_TOLERANCE = 1e-9
# States of the nominal trajectory compared with Pinocchio (evenly spaced).
COMPARED_STATES = 20


def plot_envelopes(study, path):
    joints = [o for o in study.outputs if o.startswith("q.")]
    fig, axes = plt.subplots(len(joints), 1, figsize=(8, 2.0 * len(joints)), sharex=True)
    for ax, name in zip(np.atleast_1d(axes), joints):
        ax.fill_between(study.times, study.lower[name], study.upper[name], alpha=0.35,
                        label="envelope")
        ax.plot(study.times, study.nominal[name], lw=1.0, label="nominal")
        ax.set_ylabel(f"{name[2:]}\n[{study.units[name]}]", fontsize=8)
    np.atleast_1d(axes)[0].legend(loc="upper right", fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("t [s]")
    fig.suptitle(f"ur5: {study.method}, {study.runs} runs, "
                 f"{'trusted' if study.trusted else 'NOT trusted'}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def compare_with_pinocchio(simulation):
    """The largest relative difference of M, C(q,v)v + g and every link frame between ribbon and
    Pinocchio at states of the nominal trajectory (velocities: random, seeded)."""
    arm = ribbon.load(URDF)
    model = pin.buildModelFromUrdf(URDF)
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    data = model.createData()
    assert [j["name"] for j in arm.joints()] == list(model.names[1:])
    rng = np.random.default_rng(0)
    worst = 0.0
    rows = np.linspace(0, len(simulation.times) - 1, COMPARED_STATES).astype(int)
    for q in simulation.positions[rows]:
        v = rng.standard_normal(arm.nv)
        ours = arm.dynamics(q, v)
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        pairs = [(ours["mass_matrix"], mass), (ours["bias"], pin.nle(model, data, q, v))]
        pin.framesForwardKinematics(model, data, q)
        for link, placement in ours["frames"].items():
            pairs.append((placement, data.oMf[model.getFrameId(link, pin.BODY)].homogeneous))
        for a, b in pairs:
            scale = max(1.0, float(np.max(np.abs(b))))
            worst = max(worst, float(np.max(np.abs(a - b))) / scale)
    return worst


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="target/ur5-python", help="output directory")
    out = pathlib.Path(parser.parse_args().out)
    out.mkdir(parents=True, exist_ok=True)

    def progress(p):
        print(f"  {p['phase']}: {p['records_done']}/{p['records_total']} record times", end="\r")

    study = ribbon.analyze(URDF, progress=progress)  # the sidecar beside the URDF
    print()
    print(study)
    plot_envelopes(study, out / "ur5_envelopes.png")
    study.write_mcap(out / "ur5.mcap")
    check = study.check
    print(f"check: {check['runs']} true runs, verdict: "
          f"{'trusted' if study.trusted else 'untrusted: ' + study.advice}")
    sobol = study.sobol
    final = {name: sobol["total"][name][-1] for name in study.outputs}
    for name, total in list(final.items())[:3]:
        ranked = sorted(zip(sobol["parameters"], total), key=lambda p: -p[1])
        print(f"  {name}: total Sobol' indices at t = {study.times[-1]} s: "
              + ", ".join(f"{p} {s:.2f}" for p, s in ranked))

    worst = compare_with_pinocchio(ribbon.simulate(URDF))
    verdict = "agrees with Pinocchio" if worst <= PINOCCHIO_TOLERANCE else "DIFFERS from Pinocchio"
    print(f"nominal dynamics at {COMPARED_STATES} states of the nominal run: {verdict} "
          f"(largest relative difference {worst:.1e}; M, bias, {len(ribbon.load(URDF).dynamics()['frames'])} frames)")
    print(f"wrote {out / 'ur5_envelopes.png'} and {out / 'ur5.mcap'}")
    return 0 if worst <= PINOCCHIO_TOLERANCE else 1


if __name__ == "__main__":
    sys.exit(main())
