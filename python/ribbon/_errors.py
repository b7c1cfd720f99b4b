"""The exceptions of ribbon, by the command line's exit codes (README, "Exit codes")."""


class RibbonError(Exception):
    """Any error ribbon reports; `exit_code` is the status the `ribbon` command would exit with."""

    exit_code = 1


class InputError(RibbonError, ValueError):
    """The input is at fault and nothing ran (exit 2): a bad URDF, sidecar, option or value.

    The message is the command line's: it names the file, line, key or flag (an option `x_y=` is
    the flag `--x-y`), what was expected and what to do.
    """

    exit_code = 2


class RunError(RibbonError, RuntimeError):
    """A run that started failed (exit 1): the integrator, a study, or writing a file."""

    exit_code = 1


class UntrustedResult(RibbonError):
    """The study finished, but its a-posteriori check did not trust some outputs (exit 4).

    `result` is the StudyResult all the same: its envelopes were widened to every true run made,
    yet may still be too narrow; `result.advice` says what to do.
    """

    exit_code = 4

    def __init__(self, message, result):
        super().__init__(message)
        self.result = result


class RibbonWarning(UserWarning):
    """A warning or note of ribbon's (a model, sidecar or start warning)."""
