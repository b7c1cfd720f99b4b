"""The package's dynamics against Pinocchio's on random states (a fixed-base arm and a floating
quadruped), and the example script (examples/python/ur5_study.py), which plots the ur5 study and makes
the same comparison along the nominal trajectory."""

import pathlib
import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest

import ribbon
from conftest import ROOT, robot

# Two implementations of the same recursions in double precision: agreement to this relative
# size (of the largest entry of the quantity compared) leaves room for their different orders of
# operations only.
RELATIVE_TOLERANCE = 1e-9
STATES = 10


def pinocchio_model(urdf, floating):
    if floating:
        return pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())
    return pin.buildModelFromUrdf(urdf)


def close(a, b):
    scale = max(1.0, float(np.max(np.abs(b))))
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b)))) <= RELATIVE_TOLERANCE * scale


@pytest.mark.parametrize("name, floating", [("ur5", False), ("quadruped", True)])
def test_dynamics_agree_with_pinocchio(name, floating):
    arm = ribbon.load(robot(name), floating=floating)
    model = pinocchio_model(robot(name), floating)
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    data = model.createData()
    assert (model.nq, model.nv) == (arm.nq, arm.nv)
    # Both order the coordinates depth-first along the URDF tree; check by name.
    names = [j["name"] for j in arm.joints()]
    assert names == list(model.names[1:])
    rng = np.random.default_rng(7)
    for _ in range(STATES):
        q = pin.randomConfiguration(model, -np.pi * np.ones(model.nq), np.pi * np.ones(model.nq))
        if floating:  # Pinocchio's free flyer: x y z, quaternion x y z w, as ribbon's.
            q[:3] = rng.uniform(-1, 1, 3)
        v, tau, qdd = (rng.standard_normal(model.nv) for _ in range(3))
        got = arm.dynamics(q, v, tau=tau, qdd=qdd)
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        assert close(got["mass_matrix"], mass)
        assert close(got["bias"], pin.nle(model, data, q, v))
        assert close(got["qdd"], pin.aba(model, data, q, v, tau))
        assert close(got["tau"], pin.rnea(model, data, q, v, qdd))
        pin.framesForwardKinematics(model, data, q)
        for link, placement in got["frames"].items():
            frame = model.getFrameId(link, pin.BODY)
            assert close(placement, data.oMf[frame].homogeneous), link


def test_the_example_plots_the_study_and_agrees_with_pinocchio(tmp_path):
    script = ROOT / "examples" / "python" / "ur5_study.py"
    done = subprocess.run(
        [sys.executable, str(script), "--out", str(tmp_path)],
        capture_output=True, text=True, cwd=ROOT,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "ur5_envelopes.png").stat().st_size > 10_000
    assert "agrees with Pinocchio" in done.stdout, done.stdout
