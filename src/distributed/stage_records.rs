//! The records of a merge's stages (docs/distributed.md §7): every stage the study reaches is read
//! from its shards' record blocks, after checking that its plan holds exactly the points the
//! study chose for it; the first stage without record blocks is pending.

use super::error::ShardError;
use super::plan_file::{InputFile, PlanFile};
use super::shards::ShardSet;
use super::stage_plan::{stage_directory, Stage, STAGE_PLAN_FILE};
use crate::analysis::{ForeignError, StageRecords, StageRequest, StageSource, StudyError};
use std::path::{Path, PathBuf};

/// The stages of a planned study whose record blocks lie under one directory.
pub struct ShardStages<'p> {
    plan: &'p PlanFile,
    plan_path: PathBuf,
    dir: PathBuf,
}

impl<'p> ShardStages<'p> {
    /// The stages of `plan` (read from `plan_path`) with their record blocks under `dir`.
    pub fn new(plan: &'p PlanFile, plan_path: &Path, dir: &Path) -> ShardStages<'p> {
        ShardStages {
            plan,
            plan_path: plan_path.to_path_buf(),
            dir: dir.to_path_buf(),
        }
    }

    fn source(&mut self, request: &StageRequest) -> Result<StageSource, ShardError> {
        let staged = self.plan.body.staged.is_some() || request.stage > 1;
        if request.stage > 1
            && !stage_directory(&self.dir, request.stage)
                .join(STAGE_PLAN_FILE)
                .exists()
        {
            return Ok(StageSource::Pending);
        }
        let stage = Stage::resolve(self.plan, &self.plan_path, &self.dir, request.stage)?;
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
        if bits(&stage.points) != bits(request.points) || stage.nominal != request.nominal {
            return Err(ShardError::Plan {
                path: stage.plan_path.clone(),
                message: format!(
                    "stage {} ({} phase) holds other sample points than this merge chooses for it from {}: it was made by another ribbon or from other records; {}",
                    stage.number,
                    request.phase,
                    if stage.number == 1 { "the same inputs".to_string() } else { format!("the records of stages 1..{}", stage.number - 1) },
                    if stage.number == 1 {
                        "make the plan again with this ribbon (`ribbon plan`)".to_string()
                    } else {
                        format!("remove {} and merge again", stage.directory.display())
                    }
                ),
            });
        }
        if stage.number > 1 && ShardSet::block_files(&stage.directory)?.is_empty() {
            return Ok(StageSource::Pending);
        }
        let set = ShardSet::open_stage(self.plan, &stage).map_err(|e| match e {
            // `run` defaults to the last stage planned: name the stage to run.
            ShardError::Missing {
                dir,
                missing,
                shards,
            } if staged => ShardError::Missing {
                dir,
                missing,
                shards: format!("{shards}, with `--stage {}`", stage.number),
            },
            other => other,
        })?;
        self.check_planned_from(&stage, &set)?;
        eprintln!(
            "merge: stage {} ({}): {} record blocks of {} from {}",
            stage.number,
            request.phase,
            set.files().len(),
            stage.hash,
            stage.directory.display()
        );
        Ok(StageSource::Records(Box::new(set)))
    }
}

impl ShardStages<'_> {
    /// When the stage after `stage` is planned, refuses record blocks of `stage` other than the
    /// ones its plan names (re-run with other bits or another shard count, or replaced, since the
    /// next stage's points were chosen from them).
    fn check_planned_from(&self, stage: &Stage, set: &ShardSet) -> Result<(), ShardError> {
        let next = stage.number + 1;
        let planned = stage_directory(&self.dir, next).join(STAGE_PLAN_FILE);
        if !planned.exists() {
            return Ok(());
        }
        let next = Stage::resolve(self.plan, &self.plan_path, &self.dir, next)?;
        let found = set.block_digests();
        if next.planned_from == found {
            return Ok(());
        }
        let describe = |blocks: &[InputFile]| -> String {
            let names: Vec<String> = blocks
                .iter()
                .map(|b| format!("{} ({})", b.path.display(), b.fnv1a64))
                .collect();
            names.join(", ")
        };
        let differing: Vec<String> = found
            .iter()
            .filter(|b| !next.planned_from.contains(b))
            .map(|b| b.path.display().to_string())
            .collect();
        Err(ShardError::Plan {
            path: next.plan_path.clone(),
            message: format!(
                "stage {} was planned from the record blocks {} of stage {}, but {} holds {}: {} changed after stage {} was planned (run again by another ribbon or with another shard count, or replaced); put back the blocks it names, or remove the directories of stage {} and later and merge again",
                next.number,
                describe(&next.planned_from),
                stage.number,
                stage.directory.display(),
                describe(found),
                if differing.is_empty() {
                    "some blocks it names are gone: the stage's records".to_string()
                } else {
                    differing.join(", ")
                },
                next.number,
                next.number
            ),
        })
    }
}

impl StageRecords for ShardStages<'_> {
    fn stage(&mut self, request: &StageRequest) -> Result<StageSource, StudyError> {
        self.source(request)
            .map_err(|e| StudyError::Records(ForeignError::new(e)))
    }
}
