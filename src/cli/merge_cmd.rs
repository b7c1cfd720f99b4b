//! `ribbon merge study.plan DIR [--summary F] [--csv F] [--out F.mcap] [--report DIR] [--threads N]`:
//! the last stage of a distributed study (docs/distributed.md §4). Reads the shards' record blocks
//! as the design's records and runs the stages of `analyze` on them — fit and bound, the
//! a-posteriori check (its true-model runs are simulated here), the chaos estimate, the sinks — so
//! that every output is byte-identical to `analyze` of the same study (timing fields aside).

use super::analyze_cmd::{run_study, MergeInput};
use super::run_cmd::analyze_args_of;
use super::MergeArgs;
use crate::distributed::PlanFile;
use crate::Error;

/// Runs `ribbon merge`.
pub fn run(args: &MergeArgs) -> Result<(), Error> {
    let plan = PlanFile::read(&args.plan)?;
    plan.body.urdf.check(&args.plan, "URDF")?;
    plan.body.sidecar.check(&args.plan, "sidecar")?;
    // The plan and the record blocks are inputs too: no output may overwrite them.
    let blocks: Vec<std::path::PathBuf> = std::fs::read_dir(&args.dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
                .collect()
        })
        .unwrap_or_default();
    let mut inputs = vec![("plan", args.plan.as_path())];
    inputs.extend(blocks.iter().map(|p| ("record block", p.as_path())));
    let outputs: Vec<(&str, &std::path::Path)> = [
        ("--summary", &args.summary),
        ("--csv", &args.csv),
        ("--out", &args.out),
    ]
    .into_iter()
    .filter_map(|(flag, path)| path.as_deref().map(|p| (flag, p)))
    .collect();
    crate::output::check_outputs(&inputs, &outputs)?;
    let mut analyze_args = analyze_args_of(&plan, args.threads);
    analyze_args.summary = args.summary.clone();
    analyze_args.csv = args.csv.clone();
    analyze_args.out = args.out.clone();
    analyze_args.report = args.report.clone();
    run_study(
        &analyze_args,
        Some(MergeInput {
            plan: &plan,
            plan_path: &args.plan,
            dir: &args.dir,
        }),
    )
}
