"""ribbon from Python: bound envelopes of robot motion under interval-uncertain masses, inertias
and link lengths, with numpy arrays in and out.

    import ribbon
    robot = ribbon.load("robots/ur5/ur5.urdf")
    robot.params()                      # {"paths", "values", "units"}
    robot.dynamics(q, v, tau=tau)       # mass_matrix, bias, qdd, frames
    sim = ribbon.simulate("robots/ur5/ur5.urdf")            # sim.times, sim.outputs
    study = ribbon.analyze("robots/ur5/ur5.urdf")           # study.lower/nominal/upper[...]
    study.write_mcap("ur5.mcap"); study.write_csv("ur5.csv"); study.report("report/")

The same validation and messages as the `ribbon` command: bad input raises InputError (a
ValueError), a failed run RunError, an untrusted study UntrustedResult (with `.result`); Ctrl-C
stops a run after the current step and raises KeyboardInterrupt with the partial result as
`.result`. See python/README.md.
"""

from ._errors import InputError, RibbonError, RibbonWarning, RunError, UntrustedResult
from ._ribbon import Robot, Simulation, StudyResult, __version__, analyze, load, simulate

__all__ = [
    "InputError",
    "RibbonError",
    "RibbonWarning",
    "Robot",
    "RunError",
    "Simulation",
    "StudyResult",
    "UntrustedResult",
    "__version__",
    "analyze",
    "load",
    "simulate",
]
