//! `ribbon run study.plan --shard K/N --into DIR` (or `--shards N`, K from `SLURM_ARRAY_TASK_ID`
//! or `JOB_COMPLETION_INDEX`): simulates one shard of a planned study into its record block
//! `DIR/shard-K-of-N.records.mcap` (docs/distributed.md §3). The file appears only when the shard
//! is complete (written beside it and renamed); a re-run replaces only that shard's file. A staged
//! study's shard runs the last stage planned under DIR (or `--stage K`) into
//! `DIR/stage-K/shard-K-of-N.records.mcap` (docs/distributed.md §7). The shard itself is
//! [`crate::study_front::run_shard`].

use super::RunArgs;
use crate::study_front::{run_shard, ShardRequest};
use crate::Error;

/// Runs `ribbon run`.
pub fn run(args: &RunArgs) -> Result<(), Error> {
    run_shard(&ShardRequest {
        plan: args.plan.clone(),
        shard: args.shard.clone(),
        shards: args.shards,
        into: args.into.clone(),
        stage: args.stage,
        threads: args.threads,
    })
}
