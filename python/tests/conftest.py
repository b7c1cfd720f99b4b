"""Shared fixtures: the repository root, the release `ribbon` binary (python/tests/run.sh sets
RIBBON_BIN; its absence is an error, never a skip) and a runner for it."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def robot(name):
    """A shipped robot's URDF path, e.g. robot("ur5")."""
    return str(ROOT / "robots" / name / f"{name}.urdf")


@pytest.fixture(scope="session")
def ribbon_bin():
    path = os.environ.get("RIBBON_BIN", str(ROOT / "target" / "release" / "ribbon"))
    if not os.access(path, os.X_OK):
        raise RuntimeError(
            f"the ribbon binary {path} is missing: build it (cargo build --release) or run "
            "python/tests/run.sh, which does"
        )
    return path


@pytest.fixture
def cli(ribbon_bin):
    """Runs `ribbon ARGS…`; returns (exit code, stdout, stderr)."""

    def run(*args):
        done = subprocess.run(
            [ribbon_bin, *map(str, args)], capture_output=True, text=True, cwd=ROOT
        )
        return done.returncode, done.stdout, done.stderr

    return run
