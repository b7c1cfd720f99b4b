"""Bad input raises InputError (a ValueError) with the CLI's message; an untrusted study raises
UntrustedResult carrying its result, with the CLI's exit-4 message."""

import numpy as np
import pytest

import ribbon
from conftest import robot


def cli_message(stderr):
    """The CLI's error message without its `error: ` prefix: the last `error: ` line and the
    indented lines that follow it (a long message is laid out as a headline and its clauses)."""
    lines = stderr.splitlines()
    starts = [i for i, l in enumerate(lines) if l.startswith("error: ")]
    assert starts, stderr
    block = [lines[starts[-1]][len("error: "):]]
    for l in lines[starts[-1] + 1:]:
        if not l.startswith("  "):
            break
        block.append(l)
    return "\n".join(block)


@pytest.mark.parametrize(
    "args, kwargs",
    [
        (["--method", "legendre-skan"], {"method": "legendre-skan"}),
        (["--method", "scan", "--grid", "4"], {"method": "scan", "grid": 4}),
        (["--max-runs", "1"], {"max_runs": 1}),
        (["--elements", "maybe"], {"elements": "maybe"}),
        (["--step=-0.001"], {"step": -0.001}),
        (["--method", "auto", "--design", "total"], {"method": "auto", "design": "total"}),
    ],
)
def test_analyze_input_errors_are_the_cli_s(args, kwargs, cli):
    code, _, err = cli("analyze", robot("ur5"), *args)
    assert code == 2, err
    with pytest.raises(ribbon.InputError) as caught:
        ribbon.analyze(robot("ur5"), **kwargs)
    assert isinstance(caught.value, ValueError)
    assert caught.value.exit_code == 2
    assert str(caught.value) == cli_message(err)


def test_missing_files(cli, tmp_path):
    missing = tmp_path / "nope.urdf"
    code, _, err = cli("analyze", missing)
    assert code == 2
    with pytest.raises(ribbon.InputError) as caught:
        ribbon.analyze(missing)
    assert str(caught.value) == cli_message(err)
    with pytest.raises(ribbon.InputError, match="nope.urdf"):
        ribbon.load(missing)
    with pytest.raises(ribbon.InputError, match="none.toml"):
        ribbon.analyze(robot("ur5"), sidecar=tmp_path / "none.toml")


def test_unknown_and_mistyped_keywords():
    with pytest.raises(ribbon.InputError, match="did you mean 'scan_grid'"):
        ribbon.analyze(robot("ur5"), scan_gird=11)
    with pytest.raises(ribbon.InputError, match="--order: order=four is not a non-negative integer"):
        ribbon.analyze(robot("ur5"), order="four")
    with pytest.raises(ribbon.InputError, match="--seed"):
        ribbon.analyze(robot("ur5"), seed=-1)
    with pytest.raises(ribbon.InputError, match="accepted: duration, step, alpha, floating"):
        ribbon.simulate(robot("ur5"), method="scan")


def test_set_errors_are_the_cli_s(cli):
    code, _, err = cli("simulate", robot("ur5"), "--set", "link.forearm_link.mas=2")
    assert code == 2
    with pytest.raises(ribbon.InputError) as caught:
        ribbon.simulate(robot("ur5"), set={"link.forearm_link.mas": 2})
    assert str(caught.value) == cli_message(err)
    with pytest.raises(ribbon.InputError, match="not a number"):
        ribbon.simulate(robot("ur5"), set={"link.forearm_link.mass": "heavy"})
    with pytest.raises(ribbon.InputError, match="a mass must be"):
        ribbon.load(robot("ur5")).dynamics(set={"link.forearm_link.mass": -1.0})


def test_dynamics_errors_are_the_cli_s(cli):
    code, _, err = cli("dynamics", robot("ur5"), "--q", "1,2,3")
    assert code == 2
    arm = ribbon.load(robot("ur5"))
    with pytest.raises(ribbon.InputError) as caught:
        arm.dynamics([1, 2, 3])
    assert str(caught.value) == cli_message(err)
    with pytest.raises(ribbon.InputError, match="element 2 is NaN"):
        arm.dynamics(np.array([0.0, np.nan, 0, 0, 0, 0]))
    with pytest.raises(ribbon.InputError, match="2 dimensions"):
        arm.dynamics(np.zeros((2, 3)))
    with pytest.raises(ribbon.InputError, match="norm"):
        ribbon.load(robot("ur5"), floating=True).dynamics(np.zeros(13))


def test_untrusted_result_carries_the_result(cli):
    args = ["--method", "legendre-scan", "--order", "1", "--elements", "off"]
    code, _, err = cli("analyze", robot("ur5"), *args)
    assert code == 4, err
    with pytest.raises(ribbon.UntrustedResult) as caught:
        ribbon.analyze(robot("ur5"), method="legendre-scan", order=1, elements=False)
    untrusted = caught.value
    assert untrusted.exit_code == 4
    assert str(untrusted) == cli_message(err)
    result = untrusted.result
    assert isinstance(result, ribbon.StudyResult)
    assert not result.trusted and result.advice
    assert result.check["untrusted_outputs"], result.check
    assert np.all(result.lower[result.outputs[0]] <= result.upper[result.outputs[0]])
