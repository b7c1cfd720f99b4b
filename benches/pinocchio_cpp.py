#!/usr/bin/env python3
"""ribbon's dynamics kernels against Pinocchio's, both in compiled code, in one run.

Usage (from the crate root, with the reference venv that `cargo test --release` creates):

    target/reference-venv/bin/python benches/pinocchio_cpp.py [--rounds R] [--calls N] [--batch B] [--callgrind]

What it does:
1. Builds `benches/pinocchio_cpp/timing.cpp` twice against the C++ headers and shared libraries that
   the `pin` wheel ships (`cmeel.prefix` in the venv), with Eigen and urdfdom's headers from Debian
   (`apt-get install libeigen3-dev liburdfdom-headers-dev`): `lib` calls the kernels the wheel
   compiled (`PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION`, what a user linking the library gets),
   `inline` compiles the header templates into the program with `g++ -O3 -DNDEBUG` (what Pinocchio's
   own benchmarks do). Neither uses `-march=native`; neither does ribbon.
2. Builds `benches/kernel_timing.rs` (`cargo bench --no-run`), which times ribbon's kernels the same
   way: same state, min over runs of the mean of N calls.
3. Wall time: R rounds; each round runs the three programs one after the other (the order rotates),
   per robot; each kernel's figure is its minimum over rounds. The ratio divides ribbon's time by the
   *fastest* Pinocchio variant (lib or inline; for CRBA and ABA also the faster of the WORLD and LOCAL
   conventions), so it is the harshest comparison available. Pinocchio's CRBA fills only the upper
   triangle of `M` (ribbon's returns the whole matrix): the row `crba_whole_matrix` compares
   ribbon's `crba` with Pinocchio's LOCAL CRBA plus the copy into the lower triangle its
   documentation gives (`crba_local_full`); the `crba` row stays against the upper triangle alone.
4. `--callgrind`: instructions per call under `valgrind --tool=callgrind`, as the difference between
   runs of 3000 and 1000 calls divided by 2000 (setup and URDF parsing cancel). Instruction counts do
   not depend on what else the machine is doing; they are not time (an instruction of a dependent
   chain and one of a vector loop cost differently), so both are reported.

5. Batched kernels (`ribbon::dynamics::batch`, docs/batch.md): `kernel_timing` also times ribbon's
   CRBA and RNEA over a batch of B samples (default 32; masses 1 % apart, states shifted per
   sample) and reports **µs per sample**; rows `batch_crba` and `batch_rnea` divide that by
   Pinocchio's time **per call** (one sample), the issue's "≤ 0.5× Pinocchio C++ per sample in a
   batch". With `--callgrind` their instructions are per sample: (I(3000 samples) − I(1000
   samples)) over the samples of the whole batch calls between them.

6. `--before PATH`: a `kernel_timing` executable built from an earlier commit (copy
   `target/release/deps/kernel_timing-*` aside before changing a kernel) runs in the same rounds as
   a fourth program; its ratios (and with `--callgrind` its instruction ratios) are reported beside
   the current ones, so that a change is measured before and after in one run, under one load.

Prints a JSON document on stdout and a Markdown table on stderr.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import sysconfig

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.join(ROOT, "target", "pinocchio-cpp")
DEFINES = [
    # What Pinocchio's exported CMake targets add to every consumer (lib/cmake/pinocchio).
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
    "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
    "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
    "-DPINOCCHIO_WITH_URDFDOM",
]


def cmeel_prefix():
    for base in [sysconfig.get_paths()["purelib"]] + sys.path:
        path = os.path.join(base, "cmeel.prefix")
        if os.path.isdir(os.path.join(path, "include", "pinocchio")):
            return path
    sys.exit("pinocchio_cpp.py: no cmeel.prefix/include/pinocchio; run this with "
             "target/reference-venv/bin/python after `cargo test --release` has made the venv")


def build_pinocchio(prefix):
    for header, package in [("/usr/include/eigen3/Eigen/Core", "libeigen3-dev"),
                            ("/usr/include/urdf_model/model.h", "liburdfdom-headers-dev")]:
        if not os.path.exists(header):
            sys.exit(f"pinocchio_cpp.py: {header} is missing: run `apt-get install -y {package}`")
    os.makedirs(BUILD, exist_ok=True)
    source = os.path.join(ROOT, "benches", "pinocchio_cpp", "timing.cpp")
    lib = os.path.join(prefix, "lib")
    programs = {}
    for variant, extra in [("lib", ["-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"]), ("inline", [])]:
        out = os.path.join(BUILD, f"timing-{variant}")
        if not os.path.exists(out) or os.path.getmtime(out) < os.path.getmtime(source):
            command = (["g++", "-O3", "-DNDEBUG", "-std=c++17"] + DEFINES + extra +
                       ["-I", os.path.join(prefix, "include"), "-I", "/usr/include/eigen3", source,
                        "-L", lib, "-lpinocchio_parsers", "-lpinocchio_default",
                        f"-Wl,-rpath,{os.path.realpath(lib)}", "-o", out])
            print(f"building {out}", file=sys.stderr)
            subprocess.run(command, check=True)
        programs[f"pinocchio-{variant}"] = out
    return programs


def build_ribbon():
    output = subprocess.run(
        ["cargo", "bench", "--bench", "kernel_timing", "--no-run", "--message-format=json"],
        cwd=ROOT, check=True, capture_output=True, text=True).stdout
    for line in output.splitlines():
        message = json.loads(line)
        if message.get("target", {}).get("name") == "kernel_timing" and message.get("executable"):
            return message["executable"]
    sys.exit("pinocchio_cpp.py: cargo did not report the kernel_timing executable")


def robots(prefix):
    share = os.path.join(prefix, "share", "example-robot-data", "robots")
    return [("ribbon-ur5", os.path.join(ROOT, "robots", "ur5", "ur5.urdf")),
            ("erd-ur5", os.path.join(share, "ur_description", "urdf", "ur5_robot.urdf")),
            ("erd-panda", os.path.join(share, "panda_description", "urdf", "panda.urdf"))]


def run_json(program, urdf, calls, runs, extra=()):
    args = [program, urdf, str(calls), str(runs)] + list(extra)
    return json.loads(subprocess.run(args, check=True, capture_output=True, text=True).stdout)


def instructions(program, urdf, calls, kernel, extra=()):
    result = subprocess.run(
        ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", program, urdf,
         str(calls), "1", kernel] + list(extra), check=True, capture_output=True, text=True)
    found = re.search(r"Collected\s*:\s*(\d+)", result.stderr)
    if not found:
        sys.exit(f"pinocchio_cpp.py: no instruction count from callgrind for {program}")
    return int(found.group(1))


def per_call_instructions(program, urdf, kernel):
    return (instructions(program, urdf, 3000, kernel) - instructions(program, urdf, 1000, kernel)) / 2000


def per_sample_instructions(program, urdf, kernel, batch):
    """A batched kernel's instructions per sample: `kernel_timing` runs CALLS // batch batch calls."""
    many, few = 3000, 1000
    samples = (max(many // batch, 1) - max(few // batch, 1)) * batch
    if samples <= 0:
        sys.exit(f"pinocchio_cpp.py: --batch {batch} is too large for the callgrind counts "
                 f"({many} and {few} samples); use at most {few // 2}")
    return (instructions(program, urdf, many, kernel, [str(batch)]) -
            instructions(program, urdf, few, kernel, [str(batch)])) / samples


# row -> the Pinocchio kernels its ribbon kernel is compared with (the fastest one counts).
PAIRS = {"crba": ["crba_world", "crba_local"], "rnea": ["rnea"],
         "forward_dynamics": ["aba_world", "aba_local"],
         # ribbon's per-sample time in a batch against Pinocchio's per call.
         "batch_crba": ["crba_world", "crba_local"], "batch_rnea": ["rnea"],
         # ribbon's crba (the whole matrix) against Pinocchio's crba plus the copy of its upper
         # triangle into the lower one that Pinocchio documents (it fills the upper one only).
         "crba_whole_matrix": ["crba_local_full"]}
BATCHED = {"batch_crba", "batch_rnea"}
# A row whose ribbon kernel has another name (else the row's own).
RIBBON_KERNEL = {"crba_whole_matrix": "crba"}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--calls", type=int, default=100000)
    parser.add_argument("--batch", type=int, default=32,
                        help="samples per call of ribbon's batched kernels (default 32)")
    parser.add_argument("--callgrind", action="store_true")
    parser.add_argument("--before", metavar="PATH",
                        help="a kernel_timing executable of an earlier commit, timed alongside")
    options = parser.parse_args()
    if options.before and not os.access(options.before, os.X_OK):
        sys.exit(f"pinocchio_cpp.py: --before {options.before}: not an executable file; pass a "
                 "kernel_timing binary copied from target/release/deps/ before the change")
    prefix = cmeel_prefix()
    programs = {"ribbon": build_ribbon(), **build_pinocchio(prefix)}
    if options.before:
        programs["ribbon-before"] = options.before
    ribbons = [name for name in programs if name.startswith("ribbon")]
    references = [name for name in programs if name not in ribbons]
    with open("/proc/loadavg") as handle:
        load_before = handle.read().split()[0]
    if options.batch < 1:
        sys.exit(f"pinocchio_cpp.py: --batch must be a positive integer, got {options.batch}")
    report = {"load_before": load_before, "rounds": options.rounds, "calls": options.calls,
              "batch": options.batch, "robots": []}
    for label, urdf in robots(prefix):
        if not os.path.exists(urdf):
            print(f"{label}: {urdf} not found, skipped", file=sys.stderr)
            continue
        best = {}
        names = list(programs)
        for round_index in range(options.rounds):
            order = names[round_index % len(names):] + names[:round_index % len(names)]
            for name in order:
                extra = ["all", str(options.batch)] if name in ribbons else []
                result = run_json(programs[name], urdf, options.calls, 3, extra)
                if name == "ribbon":
                    report["batch_isa"] = result.get("isa")
                    report["batch_lanes"] = result.get("lanes")
                for kernel, us in result["us"].items():
                    key = (name, kernel)
                    best[key] = min(best.get(key, float("inf")), us)
        entry = {"robot": label, "urdf": urdf, "us": {f"{n}/{k}": v for (n, k), v in best.items()},
                 "ratio": {}}
        for kernel, pinocchio_kernels in PAIRS.items():
            anchor = min(best[(n, r)] for n in references for r in pinocchio_kernels)
            for ribbon in ribbons:
                key = "ratio" if ribbon == "ribbon" else "ratio_before"
                entry.setdefault(key, {})[kernel] = best[
                    (ribbon, RIBBON_KERNEL.get(kernel, kernel))] / anchor
        if options.callgrind:
            counts = {}
            for kernel, pinocchio_kernels in PAIRS.items():
                for ribbon in ribbons:
                    if kernel in BATCHED:
                        counts[f"{ribbon}/{kernel}"] = per_sample_instructions(
                            programs[ribbon], urdf, kernel, options.batch)
                    elif kernel in RIBBON_KERNEL:
                        counts[f"{ribbon}/{kernel}"] = counts[f"{ribbon}/{RIBBON_KERNEL[kernel]}"]
                    else:
                        counts[f"{ribbon}/{kernel}"] = per_call_instructions(
                            programs[ribbon], urdf, kernel)
                for name in references:
                    for reference in pinocchio_kernels:
                        key = f"{name}/{reference}"
                        if key not in counts:
                            counts[key] = per_call_instructions(programs[name], urdf, reference)
            entry["instructions_per_call"] = counts
            for ribbon in ribbons:
                entry["instruction_ratio" if ribbon == "ribbon" else "instruction_ratio_before"] = {
                    kernel: counts[f"{ribbon}/{kernel}"] / min(
                        counts[f"{n}/{r}"] for n in references for r in pinocchio_kernels)
                    for kernel, pinocchio_kernels in PAIRS.items()}
        report["robots"].append(entry)
    with open("/proc/loadavg") as handle:
        report["load_after"] = handle.read().split()[0]
    print(json.dumps(report, indent=1))
    print(f"batch_* rows: ribbon µs **per sample** in a batch of {options.batch} "
          f"({report.get('batch_lanes')} lanes, {report.get('batch_isa')}), against Pinocchio per call",
          file=sys.stderr)
    before = options.before is not None
    print("| robot | kernel | ribbon µs | Pinocchio C++ µs (fastest variant) | ratio |"
          + (" instr. ratio |" if options.callgrind else "")
          + (" before: ratio |" + (" instr. ratio |" if options.callgrind else "") if before else ""),
          file=sys.stderr)
    columns = 5 + options.callgrind + before * (1 + options.callgrind)
    print("|" + " --- |" * columns, file=sys.stderr)
    for entry in report["robots"]:
        for kernel, pinocchio_kernels in PAIRS.items():
            anchor = min((entry["us"][f"{n}/{r}"], f"{n}/{r}") for n in references
                         for r in pinocchio_kernels)
            ribbon_us = entry["us"][f"ribbon/{RIBBON_KERNEL.get(kernel, kernel)}"]
            row = (f"| {entry['robot']} | {kernel} | {ribbon_us:.3f} | "
                   f"{anchor[0]:.3f} ({anchor[1]}) | {entry['ratio'][kernel]:.2f} |")
            if options.callgrind:
                row += f" {entry['instruction_ratio'][kernel]:.2f} |"
            if before:
                row += f" {entry['ratio_before'][kernel]:.2f} |"
                if options.callgrind:
                    row += f" {entry['instruction_ratio_before'][kernel]:.2f} |"
            print(row, file=sys.stderr)


if __name__ == "__main__":
    main()
