//! `merge`: the last stage of a distributed study (docs/distributed.md §4). Reads the shards'
//! record blocks as the design's records and runs the stages of `analyze` on them ([`run_study`])
//! — fit and bound, the a-posteriori check (its true-model runs are simulated here), the chaos
//! estimate, the sinks — so that every output is byte-identical to `analyze` of the same study
//! (timing fields aside).
//!
//! A design that chooses runs from earlier runs (screened, adaptive) runs in stages
//! (docs/distributed.md §7): when the records of every stage so far exist but the study needs
//! another, `merge` writes that stage's plan `DIR/stage-K/stage.plan`, prints one line on stdout
//! and exits with [`crate::distributed::NEXT_STAGE_EXIT_CODE`] (3), writing no output; the merge
//! after the last stage writes the outputs and exits 0.
//!
//! Does not: read the record blocks (`distributed::ShardStages`) or fit anything (`analysis/`).

use super::options::{StudyOutputs, StudyRequest};
use super::run_study::{run_study, MergeInput};
use crate::analysis::{PendingStage, StudyError};
use crate::distributed::{
    stage_directory, PlanFile, RecordBlockReader, ShardError, ShardSet, Stage, StageBody,
    StagePlanFile, STAGE_PLAN_FILE,
};
use crate::output::{check_outputs, write_atomically, write_stdout};
use crate::Error;
use std::path::{Path, PathBuf};

/// What `merge` is asked: the plan, the directory of the record blocks, the threads and where the
/// results go.
#[derive(Clone, Debug)]
pub struct MergeRequest {
    /// The plan file.
    pub plan: PathBuf,
    /// The directory of the shards' record blocks.
    pub dir: PathBuf,
    /// Worker threads for the fits and the check runs (`None`: all cores).
    pub threads: Option<usize>,
    /// The outputs (as `analyze`'s).
    pub outputs: StudyOutputs,
}

/// Merges the shards' record blocks into the study's outputs, or plans the next stage (module
/// documentation).
pub fn merge(args: &MergeRequest) -> Result<(), Error> {
    let plan = PlanFile::read(&args.plan)?;
    plan.body.urdf.check(&args.plan, "URDF")?;
    plan.body.sidecar.check(&args.plan, "sidecar")?;
    // The plan, the record blocks and the stage plans are inputs too: no output may overwrite them.
    let mut inputs_found: Vec<PathBuf> = mcap_and_plans(&args.dir);
    for k in 1..=Stage::latest_number(&plan, &args.dir) {
        inputs_found.extend(mcap_and_plans(&stage_directory(&args.dir, k)));
    }
    let mut inputs = vec![("plan", args.plan.as_path())];
    inputs.extend(inputs_found.iter().map(|p| ("record block", p.as_path())));
    let outputs: Vec<(&str, &Path)> = args
        .outputs
        .files()
        .into_iter()
        .filter_map(|(flag, path)| path.map(|p| (flag, p)))
        .collect();
    check_outputs(&inputs, &outputs)?;
    let request = StudyRequest {
        outputs: args.outputs.clone(),
        ..StudyRequest::of_plan(&plan, args.threads)
    };
    let result = run_study(
        &request,
        Some(MergeInput {
            plan: &plan,
            plan_path: &args.plan,
            dir: &args.dir,
        }),
    );
    match result {
        Err(Error::Study(StudyError::StageNeeded(pending))) => next_stage(&plan, args, &pending),
        other => other,
    }
}

/// The `.mcap` and `.plan` files directly in `dir` (none when it cannot be listed).
fn mcap_and_plans(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "mcap" || x == "plan"))
                .collect()
        })
        .unwrap_or_default()
}

/// Writes the plan of the stage the study needs (unless this merge found it already written,
/// holding the same points, with no record blocks yet), says so on stdout, and returns the
/// [`ShardError::NextStage`] that exits with [`crate::distributed::NEXT_STAGE_EXIT_CODE`].
fn next_stage(plan: &PlanFile, args: &MergeRequest, pending: &PendingStage) -> Result<(), Error> {
    let dim = plan.body.parameters.len();
    let directory = stage_directory(&args.dir, pending.stage);
    let path = directory.join(STAGE_PLAN_FILE);
    if pending.stage < 2 {
        return Err(ShardError::Plan {
            path: args.plan.clone(),
            message: format!(
                "internal: stage {} of the {} design is pending at merge",
                pending.stage, plan.body.design
            ),
        }
        .into());
    }
    let written = path.exists();
    let mut stage_hash = None;
    if !written {
        let previous = Stage::resolve(plan, &args.plan, &args.dir, pending.stage - 1)?;
        // The blocks the points were chosen from, named (and checked again) in the stage plan.
        let previous_blocks = ShardSet::open_stage(plan, &previous)?
            .block_digests()
            .to_vec();
        let file = StagePlanFile::new(StageBody {
            study_plan_hash: plan.plan_hash.clone(),
            previous_stage_hash: previous.hash,
            stage: pending.stage,
            phase: pending.phase.to_string(),
            nominal: pending.nominal,
            samples: pending.samples(dim),
            points_xi: pending
                .points
                .chunks(dim.max(1))
                .map(<[f64]>::to_vec)
                .collect(),
            previous_blocks,
        });
        stage_hash = Some(file.stage_hash.clone());
        std::fs::create_dir_all(&directory).map_err(|source| ShardError::Io {
            what: "create the stage directory",
            path: directory.clone(),
            source,
        })?;
        write_atomically(&path, "stage plan", file.to_json().as_bytes())?;
    }
    // A leftover record block in the directory of a stage just planned belongs to another
    // study's stage — unless it carries this stage's hash (its plan was removed and written again
    // the same): say so now rather than after the shards ran.
    let mut blocks_there = false;
    if let Some(hash) = &stage_hash {
        let stage = Stage::resolve(plan, &args.plan, &args.dir, pending.stage)?;
        for block in ShardSet::block_files(&directory)? {
            let ours = RecordBlockReader::open(&block, &stage.run_command(&block))
                .is_ok_and(|reader| &reader.header().plan_hash == hash);
            blocks_there |= ours;
            if ours {
                continue;
            }
            return Err(ShardError::Plan {
                path: block,
                message: format!(
                    "a record block lies in {} before its stage was planned: remove it, then run the shards of stage {}",
                    directory.display(),
                    pending.stage
                ),
            }
            .into());
        }
    }
    let samples = pending.samples(dim);
    let of = match plan.body.design.as_str() {
        "sparse-screened" => " of 2".to_string(),
        _ => String::new(),
    };
    let phase = match pending.phase {
        "adaptive" => "the next rounds of the adaptive design (stages go on until the design converges or spends its --max-runs budget)".to_string(),
        "design" => "the design built on the screening".to_string(),
        "elements" => "a round of elements (sub-boxes with their own surrogates where the check did not trust one, docs/method.md §12)".to_string(),
        other => other.to_string(),
    };
    let command = format!(
        "ribbon run {} --shard K/N --into {}",
        args.plan.display(),
        args.dir.display()
    );
    let merge_again = format!(
        "`ribbon merge {} {}` again",
        args.plan.display(),
        args.dir.display()
    );
    let then = if blocks_there {
        format!("; its record blocks are already there (the plan was written again the same): run {merge_again}")
    } else {
        format!("; run the shards again with `{command}` (or `--shards N` under a scheduler), then {merge_again}")
    };
    write_stdout(&format!(
        "stage {}{of}: {} runs ({samples} samples{}) of {phase}, planned in {}{}{then}\n",
        pending.stage,
        samples + usize::from(pending.nominal),
        if pending.nominal {
            " and the nominal run"
        } else {
            ""
        },
        path.display(),
        if written { " (already)" } else { "" },
    ))?;
    Err(ShardError::NextStage {
        stage: pending.stage,
        plan: path,
        command,
    }
    .into())
}
