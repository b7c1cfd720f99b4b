//! `ribbon merge study.plan DIR [--summary F] [--csv F] [--out F.mcap] [--report DIR] [--threads N]`:
//! the last stage of a distributed study (docs/distributed.md §4). Reads the shards' record blocks
//! as the design's records and runs the stages of `analyze` on them — fit and bound, the
//! a-posteriori check (its true-model runs are simulated here), the chaos estimate, the sinks — so
//! that every output is byte-identical to `analyze` of the same study (timing fields aside).
//!
//! A design that chooses runs from earlier runs (screened, adaptive) runs in stages
//! (docs/distributed.md §7): when the records of every stage so far exist but the study needs
//! another, `merge` writes that stage's plan `DIR/stage-K/stage.plan`, prints one line on stdout
//! and exits with [`crate::distributed::NEXT_STAGE_EXIT_CODE`] (3), writing no output; the merge
//! after the last stage writes the outputs and exits 0. The merge itself is
//! [`crate::study_front::merge`].

use super::MergeArgs;
use crate::study_front::{merge, MergeRequest, StudyOutputs};
use crate::Error;

/// Runs `ribbon merge`.
pub fn run(args: &MergeArgs) -> Result<(), Error> {
    merge(&MergeRequest {
        plan: args.plan.clone(),
        dir: args.dir.clone(),
        threads: args.threads,
        outputs: StudyOutputs {
            summary: args.summary.clone(),
            csv: args.csv.clone(),
            out: args.out.clone(),
            report: args.report.clone(),
        },
    })
}
