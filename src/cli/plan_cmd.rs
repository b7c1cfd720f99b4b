//! `ribbon plan ROBOT.urdf [analyze options] --plan study.plan`: the first stage of a distributed
//! study (docs/distributed.md): writes the plan file and prints one line on stdout with the runs,
//! the record-block bytes and the expected wall time per shard from a short calibration run. The
//! planning itself is [`crate::study_front::plan_study`].

use super::PlanArgs;
use crate::study_front::plan_study;
use crate::Error;

/// Runs `ribbon plan`.
pub fn run(args: &PlanArgs) -> Result<(), Error> {
    plan_study(&args.analyze.request(), &args.plan)
}
