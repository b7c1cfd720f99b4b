"""An independent reference for a closed loop: the planar four-bar in one minimal coordinate.

ribbon integrates the four-bar as an index-3 DAE (three joint angles, a planar pin closing the
loop, HHT-I3). This script does not: it takes the crank angle θ as the only coordinate, solves the
loop in closed form (the coupler tip on the circle about the crank tip meets the rocker tip on the
circle about the rocker pivot; velocities and accelerations from the differentiated loop
equations), takes the mass matrix M(q) and the bias forces b(q, q̇) (gravity, Coriolis) from
Pinocchio, and integrates the projected equation of motion

    Jᵀ M J θ̈ = −Jᵀ (M q̈₀ + b),   q̇ = J θ̇,   q̈ = J θ̈ + q̈₀,

(J = dq/dθ, q̈₀ the joint accelerations at θ̈ = 0) with classical RK4 at a small step. The link
lengths come from the model's joint and frame placements, the branch of the loop from the given
initial angles. Prints JSON: the record times and the three joint angles at each.

Usage: four_bar_reference.py URDF --q0 θ φrel ψ --crank-rate ω --duration T --rate R --step h
       [--gravity gx gy gz]
"""

import argparse
import json
import math

import numpy as np
import pinocchio as pin


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("urdf")
    parser.add_argument("--q0", type=float, nargs=3, required=True)
    parser.add_argument("--crank-rate", type=float, required=True)
    parser.add_argument("--duration", type=float, required=True)
    parser.add_argument("--rate", type=float, required=True)
    parser.add_argument("--step", type=float, required=True)
    parser.add_argument("--gravity", type=float, nargs=3, default=[0.0, -9.81, 0.0])
    options = parser.parse_args()

    model = pin.buildModelFromUrdf(options.urdf)
    model.gravity.linear = np.array(options.gravity)
    data = model.createData()
    names = ["crank_joint", "coupler_joint", "rocker_joint"]
    joints = [model.getJointId(n) for n in names]

    def frame_x(name):
        return model.frames[model.getFrameId(name)].placement.translation[0]

    a = model.jointPlacements[model.getJointId("coupler_joint")].translation[0]  # crank
    d = model.jointPlacements[model.getJointId("rocker_joint")].translation[0]   # ground
    b = frame_x("coupler_tip")   # coupler
    c = frame_x("rocker_tip")    # rocker

    def close(theta, branch):
        """Absolute coupler and rocker angles (φ, ψ) at crank angle θ on the given branch."""
        px, py = a * math.cos(theta), a * math.sin(theta)
        dx, dy = d - px, -py
        r = math.hypot(dx, dy)
        # The coupler tip C: |C − P| = b, |C − O4| = c; along P→O4 by l, off it by h.
        l = (b * b - c * c + r * r) / (2.0 * r)
        h = math.sqrt(max(b * b - l * l, 0.0))
        ux, uy = dx / r, dy / r
        cx = px + l * ux - branch * h * uy
        cy = py + l * uy + branch * h * ux
        return math.atan2(cy - py, cx - px), math.atan2(cy, cx - d)

    theta0, coupler0, rocker0 = options.q0
    phi0 = theta0 + coupler0
    branch = min((1.0, -1.0), key=lambda s: abs(close(theta0, s)[0] - phi0))

    def unwrap(angle, near):
        return angle + 2.0 * math.pi * round((near - angle) / (2.0 * math.pi))

    def kinematics(theta, theta_dot, theta_ddot, previous):
        phi, psi = close(theta, branch)
        phi, psi = unwrap(phi, previous[0]), unwrap(psi, previous[1])
        A = np.array([[-b * math.sin(phi), c * math.sin(psi)],
                      [b * math.cos(phi), -c * math.cos(psi)]])
        phi_dot, psi_dot = np.linalg.solve(
            A, [a * math.sin(theta) * theta_dot, -a * math.cos(theta) * theta_dot])
        rhs = [a * math.cos(theta) * theta_dot ** 2 + a * math.sin(theta) * theta_ddot
               + b * math.cos(phi) * phi_dot ** 2 - c * math.cos(psi) * psi_dot ** 2,
               a * math.sin(theta) * theta_dot ** 2 - a * math.cos(theta) * theta_ddot
               + b * math.sin(phi) * phi_dot ** 2 - c * math.sin(psi) * psi_dot ** 2]
        phi_ddot, psi_ddot = np.linalg.solve(A, rhs)
        q = (theta, phi - theta, psi)
        v = (theta_dot, phi_dot - theta_dot, psi_dot)
        acc = (theta_ddot, phi_ddot - theta_ddot, psi_ddot)
        return q, v, acc, (phi, psi)

    def configuration(angles):
        """Pinocchio's q: (cos, sin) for a continuous joint, the angle for a revolute one."""
        out = np.zeros(model.nq)
        for joint, angle in zip(joints, angles):
            i = model.idx_qs[joint]
            if model.nqs[joint] == 2:
                out[i], out[i + 1] = math.cos(angle), math.sin(angle)
            else:
                out[i] = angle
        return out

    def joint_vector(values):
        """A tangent vector (velocities, accelerations) in Pinocchio's order."""
        out = np.zeros(model.nv)
        for joint, value in zip(joints, values):
            out[model.idx_vs[joint]] = value
        return out

    state = {"angles": (phi0, rocker0)}

    def accel(theta, theta_dot):
        q, v, acc0, angles = kinematics(theta, theta_dot, 0.0, state["angles"])
        _, _, acc1, _ = kinematics(theta, theta_dot, 1.0, state["angles"])
        J = joint_vector(acc1) - joint_vector(acc0)       # dq/dθ (the θ̈ coefficient)
        qv, vv, a0 = configuration(q), joint_vector(v), joint_vector(acc0)
        M = pin.crba(model, data, qv)
        M = np.triu(M) + np.triu(M, 1).T
        bias = pin.nonLinearEffects(model, data, qv, vv)
        return -(J @ (M @ a0 + bias)) / (J @ M @ J)

    h = options.step
    steps_per_record = round(1.0 / (options.rate * h))
    records = round(options.duration * options.rate)
    theta, omega = theta0, options.crank_rate
    times, rows = [], []
    for k in range(records + 1):
        q, _, _, angles = kinematics(theta, omega, 0.0, state["angles"])
        state["angles"] = angles
        times.append(k / options.rate)
        rows.append(q)
        if k == records:
            break
        for _ in range(steps_per_record):
            k1t, k1w = omega, accel(theta, omega)
            k2t, k2w = omega + 0.5 * h * k1w, accel(theta + 0.5 * h * k1t, omega + 0.5 * h * k1w)
            k3t, k3w = omega + 0.5 * h * k2w, accel(theta + 0.5 * h * k2t, omega + 0.5 * h * k2w)
            k4t, k4w = omega + h * k3w, accel(theta + h * k3t, omega + h * k3w)
            theta += h / 6.0 * (k1t + 2 * k2t + 2 * k3t + k4t)
            omega += h / 6.0 * (k1w + 2 * k2w + 2 * k3w + k4w)
            state["angles"] = kinematics(theta, omega, 0.0, state["angles"])[3]
    json.dump({"times": times,
               "q": {n: [row[i] for row in rows] for i, n in enumerate(names)},
               "lengths": {"crank": a, "coupler": b, "rocker": c, "ground": d}}, __import__("sys").stdout)


if __name__ == "__main__":
    main()
