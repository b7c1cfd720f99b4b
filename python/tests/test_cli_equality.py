"""The package's arrays and files against the CLI's on the same studies: to the last bit."""

import csv
import json

import numpy as np
import pytest

import ribbon
from conftest import robot

# Three shipped robots: a serial arm, and two loops (index-3 constraint rows).
ROBOTS = ["ur5", "slider_crank", "four_bar"]


def read_csv(path):
    """The CSV's header and its numbers as float64 (Python's float() reads Rust's shortest
    round-trip text back to the same bits)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in row] for row in rows[1:]])


def same_bits(a, b):
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


@pytest.mark.parametrize("name", ROBOTS)
def test_analyze_arrays_equal_the_cli_csv(name, cli, tmp_path):
    code, _, err = cli("analyze", robot(name), "--csv", tmp_path / "cli.csv",
                       "--summary", tmp_path / "cli.json", "--out", tmp_path / "cli.mcap")
    assert code == 0, err
    header, table = read_csv(tmp_path / "cli.csv")
    study = ribbon.analyze(robot(name))
    assert same_bits(study.times, table[:, 0])
    columns = {h: table[:, i] for i, h in enumerate(header)}
    assert len(study.outputs) >= 3
    for output in study.outputs:
        for series in ("lower", "nominal", "upper"):
            assert same_bits(getattr(study, series)[output], columns[f"{output}.{series}"]), (
                f"{name}: {output}.{series}"
            )
    # The summary's error estimates and check, as the CLI wrote them.
    with open(tmp_path / "cli.json") as f:
        summary = json.load(f)
    for entry in summary["outputs"]:
        assert same_bits(study.error_estimate[entry["name"]], entry["error_estimate"])
    assert study.check == summary["stats"]["check"]
    assert study.summary["sensitivities"] == summary["sensitivities"]
    # The files the result writes are the CLI's, byte for byte.
    study.write_csv(tmp_path / "py.csv")
    assert (tmp_path / "py.csv").read_bytes() == (tmp_path / "cli.csv").read_bytes()
    study.write_mcap(tmp_path / "py.mcap")
    assert (tmp_path / "py.mcap").read_bytes() == (tmp_path / "cli.mcap").read_bytes()
    # The summary file: the CLI's but for the timings.
    study.write_summary(tmp_path / "py.json")
    with open(tmp_path / "py.json") as f:
        written = json.load(f)
    assert written["outputs"] == summary["outputs"]
    assert written["parameters"] == summary["parameters"]
    assert written["stats"]["check"] == summary["stats"]["check"]


def test_report_writes_the_cli_s_page(cli, tmp_path):
    code, _, err = cli("analyze", robot("ur5"), "--report", tmp_path / "cli")
    assert code == 0, err
    study = ribbon.analyze(robot("ur5"))
    study.report(tmp_path / "py")
    cli_files = sorted(p.name for p in (tmp_path / "cli").iterdir())
    assert sorted(p.name for p in (tmp_path / "py").iterdir()) == cli_files
    page = (tmp_path / "py" / "report.md").read_text()
    assert all(f"{o}" in page for o in study.outputs)
    assert study.table().splitlines()[0] in page
    # Refused like the CLI's outputs (never a directory, never an input).
    with pytest.raises(ribbon.InputError, match="directory"):
        study.write_csv(tmp_path)


def test_simulate_arrays_equal_the_cli_csv(cli, tmp_path):
    name = "double_pendulum"
    code, _, err = cli("simulate", robot(name), "--csv", tmp_path / "cli.csv",
                       "--set", "link.bar1.mass=1.25", "--duration", "1.5")
    assert code == 0, err
    header, table = read_csv(tmp_path / "cli.csv")
    sim = ribbon.simulate(robot(name), set={"link.bar1.mass": 1.25}, duration=1.5)
    assert same_bits(sim.times, table[:, 0])
    assert list(sim.outputs) == header[1:]
    for i, output in enumerate(header[1:], start=1):
        assert same_bits(sim.outputs[output], table[:, i]), output
    sim.write_csv(tmp_path / "py.csv")
    assert (tmp_path / "py.csv").read_bytes() == (tmp_path / "cli.csv").read_bytes()


def test_dynamics_equal_the_cli_json(cli):
    q = [0.3, -1.1, 0.7, 0.2, -0.4, 1.3]
    v = [0.5, -0.25, 0.125, 1.0, -2.0, 0.75]
    tau = [1.0, -20.0, 5.0, 0.5, 0.25, -0.125]
    text = lambda x: ",".join(repr(float(e)) for e in x)  # noqa: E731
    code, out, err = cli("dynamics", robot("ur5"), "--q", text(q), "--v", text(v),
                         "--tau", text(tau), "--qdd", text(v), "--json")
    assert code == 0, err
    expected = json.loads(out)
    got = ribbon.load(robot("ur5")).dynamics(q, v, tau=tau, qdd=v)
    assert same_bits(got["mass_matrix"], expected["mass_matrix"])
    for key in ("bias", "qdd", "tau"):
        assert same_bits(got[key], expected[key]), key
    for link, frame in expected["frames"].items():
        assert same_bits(got["frames"][link][:3, 3], frame["position"]), link
        assert same_bits(got["frames"][link][:3, :3], frame["rotation"]), link


def test_params_equal_the_cli_json(cli):
    code, out, err = cli("params", robot("ur5"), "--json")
    assert code == 0, err
    expected = json.loads(out)
    got = ribbon.load(robot("ur5")).params()
    assert got["paths"] == [p["path"] for p in expected]
    assert got["units"] == [p["unit"] for p in expected]
    assert same_bits(got["values"], [p["nominal"] for p in expected])
