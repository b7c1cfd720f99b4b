//! `ribbon compare ROBOT.urdf [--uncertainty F] [--report DIR] [--reference-grid N] [--orders …]
//! [--methods …] [--samples …] [--threads N] [--duration T] [--step H] [--alpha A]`: what accuracy
//! costs in time. Runs the true-model scan as the reference, then every method (and order, and Monte
//! Carlo size) on the same scene, and reports model runs, wall time and the docs/method.md §4 error of
//! each against the reference: a table on stdout, and in the report directory `report.md`,
//! `compare.json`, `error_vs_time.{svg,png}` and `envelope.{svg,png}` (the widest output, reference vs the
//! highest-order legendre-scan run). The comparison itself is [`crate::study_front::compare`].

use super::CompareArgs;
use crate::study_front::{compare, CompareRequest};
use crate::Error;

/// Runs `ribbon compare`.
pub fn run(args: &CompareArgs) -> Result<(), Error> {
    compare(&CompareRequest {
        scene: args.scene.inputs(),
        report: args.report.clone(),
        reference: args.reference.clone(),
        reference_grid: args.reference_grid,
        methods: args.methods.clone(),
        max_runs: args.max_runs,
        orders: args.orders.clone(),
        samples: args.samples.clone(),
        threads: args.threads,
    })
}
