#!/usr/bin/env python3
"""Instructions per step, ribbon's HHT-I3 step against MuJoCo's Euler step: a load-free anchor.

Usage (from the crate root; the MuJoCo venv that `cargo bench --bench hht_batch` makes, or any
Python with `mujoco` 4.0 and numpy; valgrind from Debian's `valgrind` package):

    target/mujoco-venv/bin/python benches/step_instructions.py [--steps N] [ROBOT ...]

Besides the scalar step it counts the lock-step step per sample: `BatchStepper::step` in
`hht_batch --count-steps ROBOT 4` (one 1 s fall of a batch of 4 samples, masses 1 % apart; issue 16
item 2), divided by 4 x 1000 sample-steps. Each is counted twice: with every step computing the
reported velocity (`HhtIntegrator::step`), and as a study steps when it records every 10 steps (the
shipped scenes: 100 Hz records, 1 ms steps), only the step into a record computing it
(`--record-every 10`, `ReportedVelocity::Skipped` between; the records have the same bits). The two
differ only on robots with constraint rows (the panda's mimic joint, the four-bar's loop), where
the reported velocity is a projection (docs/method.md §5, "Velocity drift").

Why: MuJoCo's µs per step moved by up to 1.8x between sessions on this shared machine (the same
script, the same wheel), so a time ratio from one run says as much about the machine's state as
about the two codes. Instruction counts do not depend on load. They are not time either (a dependent
chain and a vector loop cost differently per instruction), so benches/README.md reports both.

What is counted, under `valgrind --tool=callgrind --toggle-collect=FUNCTION` (collection on only
inside FUNCTION and everything it calls):
- MuJoCo: `mj_step`, called N times (default 1000: the 1 s of the bench problem) from Python on the
  model and start `benches/mujoco_timing.py` builds (its `load` and `initial_state`; Euler, contacts
  and limits off, equalities on) — the same problem as the time bench.
- ribbon: `HhtIntegrator::advance` (what `HhtIntegrator::step` calls) in `hht_step --count-steps
  ROBOT N` (the bench binary's mode for this; the same problem from `benches/support/fall.rs`),
  after the start, which is not counted.
Per step = collected instructions / N. Robots: ribbon-ur5, erd-ur5, erd-panda (from the reference
venv that `cargo test --release` makes; skipped with a line on stderr if missing),
ribbon-quadruped, ribbon-four-bar. Prints a Markdown table on stdout.
"""

import glob
import json
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "benches"))
import mujoco_timing  # noqa: E402  (the problem definitions, shared with the time bench)

RIBBON_STEP = "ribbon::integrate::hht::HhtIntegrator::advance"
RECORD_EVERY = 10
BATCH_STEP = "ribbon::simulate::batch_step::BatchStepper::step"
BATCH_SIZE = 4
MUJOCO_STEP = "mj_step"

# Run under valgrind in a child Python: the MuJoCo side of one robot.
MUJOCO_CHILD = """
import sys
sys.path.insert(0, {benches!r})
import mujoco, mujoco_timing
path, n = {path!r}, {steps}
model, _, _ = mujoco_timing.load(path, mujoco.mjtIntegrator.mjINT_EULER, True)
data = mujoco.MjData(model)
data.qpos[:], data.qvel[:] = mujoco_timing.initial_state(model, path)
mujoco.mj_forward(model, data)
for _ in range(n):
    mujoco.mj_step(model, data)
"""


def collected(command, function):
    result = subprocess.run(
        ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
         f"--toggle-collect={function}"] + command,
        cwd=ROOT, capture_output=True, text=True)
    found = re.search(r"Collected\s*:\s*(\d+)", result.stderr)
    if result.returncode != 0 or not found:
        sys.exit(f"step_instructions.py: callgrind of {command[:3]} failed:\n{result.stderr[-2000:]}")
    return int(found.group(1)), result.stdout


def bench_binary(name):
    output = subprocess.run(
        ["cargo", "bench", "--bench", name, "--no-run", "--message-format=json"],
        cwd=ROOT, check=True, capture_output=True, text=True).stdout
    for line in output.splitlines():
        message = json.loads(line)
        if message.get("target", {}).get("name") == name and message.get("executable"):
            return message["executable"]
    sys.exit(f"step_instructions.py: cargo did not report the {name} executable")


def robot_paths():
    venv = os.path.join(ROOT, "target", "reference-venv")
    robots = [("ribbon-ur5", os.path.join(ROOT, "robots/ur5/ur5.urdf"))]
    found = sorted(glob.glob(os.path.join(venv, mujoco_timing.ERD_GLOB)))
    for label, relative in mujoco_timing.ERD_ROBOTS:
        path = os.path.join(found[-1], relative) if found else ""
        if os.path.isfile(path):
            robots.append((label, path))
        else:
            print(f"{label}: skipped, not found under {venv} (run `cargo test --release` once)",
                  file=sys.stderr)
    robots.append(("ribbon-quadruped", os.path.join(ROOT, "robots/quadruped/quadruped.urdf")))
    robots.append(("ribbon-four-bar", os.path.join(ROOT, "robots/four_bar/four_bar.urdf")))
    return robots


def main(argv):
    steps, only = 1000, []
    i = 0
    while i < len(argv):
        if argv[i] == "--steps":
            steps = int(argv[i + 1])
            i += 1
        elif argv[i] in ("-h", "--help"):
            print(__doc__)
            return
        else:
            only.append(argv[i])
        i += 1
    if not 1 <= steps <= 1000:
        sys.exit("step_instructions.py: --steps must be 1 to 1000 (one 1 s fall)")
    binary = bench_binary("hht_step")
    batch_binary = bench_binary("hht_batch")
    benches = os.path.join(ROOT, "benches")
    print(f"| robot | ribbon HHT step (Newton it./step) | recording every {RECORD_EVERY} "
          f"| batch of 4, per sample | recording every {RECORD_EVERY} | MuJoCo Euler step "
          f"| ratio: step, batch per sample | recording every {RECORD_EVERY} |")
    print("|---|---|---|---|---|---|---|---|")
    for label, path in robot_paths():
        if only and label not in only:
            continue
        every = ["--record-every", str(RECORD_EVERY)]
        ribbon, stdout = collected([binary, "--count-steps", label, str(steps)], RIBBON_STEP)
        stats = json.loads(stdout.strip().splitlines()[-1])
        recording, _ = collected([binary, "--count-steps", label, str(steps)] + every,
                                 RIBBON_STEP)
        per_sample, batch_steps = [], None
        for extra in ([], every):
            batch, stdout = collected(
                [batch_binary, "--count-steps", label, str(BATCH_SIZE)] + extra, BATCH_STEP)
            batch_steps = json.loads(stdout.strip().splitlines()[-1])["steps"]
            per_sample.append(batch / (BATCH_SIZE * batch_steps))
        child = MUJOCO_CHILD.format(benches=benches, path=path, steps=steps)
        mujoco, _ = collected([sys.executable, "-c", child], MUJOCO_STEP)
        mj = mujoco / steps
        print(f"| {label} | {ribbon / steps:,.0f} ({stats['newton_iterations'] / steps:.2f}) "
              f"| {recording / steps:,.0f} | {per_sample[0]:,.0f} | {per_sample[1]:,.0f} "
              f"| {mj:,.0f} | {ribbon / steps / mj:.2f}, {per_sample[0] / mj:.2f} "
              f"| {recording / steps / mj:.2f}, {per_sample[1] / mj:.2f} |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
