//! The stages of a staged study on disk (docs/distributed.md §7): stage 1 is described by the
//! study plan itself; stage k ≥ 2 by `DIR/stage-k/stage.plan`, written by the `merge` that chose
//! its points, hash-linked to the study plan and to stage k − 1. The record blocks of stage k lie
//! beside its plan, `DIR/stage-k/shard-K-of-N.records.mcap`, and carry the stage's hash. The plan
//! of stage k also names the record blocks of stage k − 1 it was planned from (file name and
//! FNV-1a 64 of the bytes), so a merge that replays stage k − 1 refuses a block replaced since.

use super::error::ShardError;
use super::hash::fnv1a64;
use super::plan_file::{first_difference, InputFile, PlanFile};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The `format` field of a stage plan.
pub const STAGE_PLAN_FORMAT: &str = "ribbon-stage-plan";
/// The version of the stage plan format this build writes and reads: 2 since a stage plan names
/// the record blocks it was planned from (`previous_blocks`).
pub const STAGE_PLAN_VERSION: u32 = 2;
/// The file name of a stage's plan in its directory.
pub const STAGE_PLAN_FILE: &str = "stage.plan";

/// The directory of stage `stage` (from 1) of a staged study in `dir`: `dir/stage-K`.
pub fn stage_directory(dir: &Path, stage: usize) -> PathBuf {
    dir.join(format!("stage-{stage}"))
}

/// What a stage plan fixes; its canonical JSON is what the stage hash covers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageBody {
    /// The study plan's hash.
    pub study_plan_hash: String,
    /// The hash of stage `stage − 1` (the study plan's hash for stage 2).
    pub previous_stage_hash: String,
    /// The stage's number, from 2 (stage 1 is the study plan).
    pub stage: usize,
    /// Its phase: `design` (of a screened design), `adaptive` (a round) or `elements` (a round
    /// of splitting the box, docs/method.md §12).
    pub phase: String,
    /// Whether its first shard also runs the nominal run.
    pub nominal: bool,
    /// Design samples of the stage (the nominal run not counted).
    pub samples: usize,
    /// The samples' points in standard coordinates ξ ∈ [-1, 1]^d, one row per sample.
    pub points_xi: Vec<Vec<f64>>,
    /// The record blocks of stage `stage − 1` whose records chose these points: file name (in
    /// that stage's directory) and FNV-1a 64 of its bytes, in file name order.
    pub previous_blocks: Vec<InputFile>,
}

/// A stage plan file: format, version, hash and body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StagePlanFile {
    /// [`STAGE_PLAN_FORMAT`].
    pub format: String,
    /// [`STAGE_PLAN_VERSION`].
    pub version: u32,
    /// FNV-1a 64 of the body's canonical JSON, 16 lowercase hex digits: the stage's identity,
    /// written into its record blocks.
    pub stage_hash: String,
    /// The stage.
    pub body: StageBody,
}

impl StagePlanFile {
    /// A stage plan around `body`, with its hash.
    pub fn new(body: StageBody) -> StagePlanFile {
        let canonical = serde_json::to_string(&body).unwrap_or_default();
        StagePlanFile {
            format: STAGE_PLAN_FORMAT.to_string(),
            version: STAGE_PLAN_VERSION,
            stage_hash: format!("{:016x}", fnv1a64(canonical.as_bytes())),
            body,
        }
    }

    /// The stage plan as JSON text (pretty, ending in a newline).
    pub fn to_json(&self) -> String {
        let mut text = serde_json::to_string_pretty(self).unwrap_or_default();
        text.push('\n');
        text
    }

    /// Reads and checks a stage plan: format, version, hash, that its text is byte for byte the
    /// one this ribbon writes for its content (so a damaged byte anywhere, even one the parse
    /// would forgive, is refused), and that its points have `dim` coordinates. `remedy` says what
    /// to do about a refused one.
    pub fn read(path: &Path, dim: usize, remedy: &str) -> Result<StagePlanFile, ShardError> {
        let bad = |message: String| ShardError::Plan {
            path: path.to_path_buf(),
            message,
        };
        let bytes = std::fs::read(path).map_err(|source| ShardError::Io {
            what: "read the stage plan",
            path: path.to_path_buf(),
            source,
        })?;
        let text = String::from_utf8(bytes).map_err(|e| {
            bad(format!(
                "byte {} is not UTF-8 text: it was damaged; {remedy}",
                e.utf8_error().valid_up_to()
            ))
        })?;
        let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            bad(format!(
                "not JSON ({e}): it was damaged (stage plans are written by `ribbon merge`); {remedy}"
            ))
        })?;
        if value.get("format").and_then(|f| f.as_str()) != Some(STAGE_PLAN_FORMAT)
            || value.get("version").and_then(|v| v.as_u64()) != Some(u64::from(STAGE_PLAN_VERSION))
        {
            return Err(bad(format!(
                "not a ribbon stage plan of version {STAGE_PLAN_VERSION} (\"format\": \"{STAGE_PLAN_FORMAT}\"); {remedy}"
            )));
        }
        let plan: StagePlanFile =
            serde_json::from_value(value).map_err(|e| bad(format!("{e}; {remedy}")))?;
        let again = StagePlanFile::new(plan.body.clone());
        if again.stage_hash != plan.stage_hash {
            return Err(bad(format!(
                "its body hashes to {}, not the {} it records: the stage plan was edited or damaged; {remedy}",
                again.stage_hash, plan.stage_hash
            )));
        }
        if let Some(at) = first_difference(&text, &again.to_json()) {
            return Err(bad(format!(
                "its text differs at byte {at} from the text ribbon writes for its content: it was edited or damaged; {remedy}"
            )));
        }
        if plan.body.points_xi.len() != plan.body.samples
            || plan.body.points_xi.iter().any(|p| p.len() != dim)
        {
            return Err(bad(format!(
                "{} samples of {dim} parameters declared, but the points do not match; {remedy}",
                plan.body.samples
            )));
        }
        Ok(plan)
    }
}

/// One stage of a planned study, resolved: its identity, samples and where its files go.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// The stage's number, from 1 (a study of a fixed design has stage 1 only).
    pub number: usize,
    /// The hash its record blocks carry: the study plan's for stage 1, the stage plan's after.
    pub hash: String,
    /// Its sample points, row-major `samples × d`.
    pub points: Vec<f64>,
    /// Design samples (the nominal run not counted).
    pub samples: usize,
    /// Whether its first shard also runs the nominal run.
    pub nominal: bool,
    /// The directory of its record blocks: `DIR` for a fixed design, `DIR/stage-K` for a staged
    /// one.
    pub directory: PathBuf,
    /// The file that defines it: the study plan, or the stage plan.
    pub plan_path: PathBuf,
    /// The study plan.
    pub study_plan_path: PathBuf,
    /// The shard directory given to `run` and `merge` (`DIR`).
    pub root: PathBuf,
    /// Whether the study runs in stages (its shards are run with `--stage`).
    pub staged: bool,
    /// The record blocks of the stage before that this stage's points were chosen from (file
    /// name and FNV-1a 64), as its stage plan names them; none for stage 1.
    pub planned_from: Vec<InputFile>,
}

impl Stage {
    /// Stage 1 of `plan` (the only stage of a fixed design), its record blocks under `dir`.
    pub fn first(plan: &PlanFile, plan_path: &Path, dir: &Path) -> Stage {
        let staged = plan.body.staged.as_ref();
        Stage {
            number: 1,
            hash: plan.plan_hash.clone(),
            points: plan.points(),
            samples: plan.body.samples,
            nominal: staged.is_none_or(|s| s.nominal),
            directory: match staged {
                Some(_) => stage_directory(dir, 1),
                None => dir.to_path_buf(),
            },
            plan_path: plan_path.to_path_buf(),
            study_plan_path: plan_path.to_path_buf(),
            root: dir.to_path_buf(),
            staged: staged.is_some(),
            planned_from: Vec::new(),
        }
    }

    /// The command that (re)writes the record block `file` of this stage (a
    /// `shard-K-of-N.records.mcap` name): `ribbon run PLAN --shard K/N --into DIR`, with
    /// `--stage S` for a staged study.
    pub fn run_command(&self, file: &Path) -> String {
        let shard = file
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_prefix("shard-")?.strip_suffix(".records.mcap"))
            .and_then(|kn| {
                let (k, n) = kn.split_once("-of-")?;
                let (k, n) = (k.parse::<usize>().ok()?, n.parse::<usize>().ok()?);
                Some(format!("{k}/{n}"))
            })
            .unwrap_or_else(|| "K/N".to_string());
        let stage = if self.staged {
            format!(" --stage {}", self.number)
        } else {
            String::new()
        };
        format!(
            "ribbon run {} --shard {shard} --into {}{stage}",
            self.study_plan_path.display(),
            self.root.display()
        )
    }

    /// Stage `number` of `plan` with its stage plans under `dir`, checking the chain of hashes
    /// from the study plan to it (each stage plan names the study plan and the stage before).
    /// Stages after the first are a staged design's later rounds, or the element rounds of a
    /// study whose first check did not trust its surrogate (docs/method.md §12), for a fixed
    /// design too.
    pub fn resolve(
        plan: &PlanFile,
        plan_path: &Path,
        dir: &Path,
        number: usize,
    ) -> Result<Stage, ShardError> {
        let mut stage = Stage::first(plan, plan_path, dir);
        if number <= 1 {
            return Ok(stage);
        }
        let dim = plan.body.parameters.len();
        for k in 2..=number {
            let directory = stage_directory(dir, k);
            let path = directory.join(STAGE_PLAN_FILE);
            if !path.exists() {
                return Err(ShardError::Plan {
                    path: path.clone(),
                    message: format!(
                        "stage {k} has not been planned: `ribbon merge {} {}` plans it after stage {} has run",
                        plan_path.display(),
                        dir.display(),
                        k - 1
                    ),
                });
            }
            let remedy = format!(
                "remove it and run `ribbon merge {} {}` again: the merge writes the plan of stage {k} again from the records of the stages before it (the same points and hash, so the record blocks of stage {k} stay valid)",
                plan_path.display(),
                dir.display()
            );
            let file = StagePlanFile::read(&path, dim, &remedy)?;
            let b = &file.body;
            if b.study_plan_hash != plan.plan_hash
                || b.stage != k
                || b.previous_stage_hash != stage.hash
            {
                return Err(ShardError::Plan {
                    path,
                    message: format!(
                        "it is stage {} of study {} after stage {}, but this is stage {k} of study {} after stage {}: it belongs to another study or was moved; remove its directory and merge again",
                        b.stage, b.study_plan_hash, b.previous_stage_hash, plan.plan_hash, stage.hash
                    ),
                });
            }
            stage = Stage {
                number: k,
                hash: file.stage_hash.clone(),
                points: b.points_xi.iter().flatten().copied().collect(),
                samples: b.samples,
                nominal: b.nominal,
                directory,
                plan_path: path,
                study_plan_path: plan_path.to_path_buf(),
                root: dir.to_path_buf(),
                staged: true,
                planned_from: b.previous_blocks.clone(),
            };
        }
        Ok(stage)
    }

    /// The last stage planned under `dir` for `plan`: the highest k with `DIR/stage-k/stage.plan`
    /// (counting up from 2 without gaps), else 1. (The plan is not needed to count: any study may
    /// have later stages, docs/method.md §12.)
    pub fn latest_number(_plan: &PlanFile, dir: &Path) -> usize {
        let mut k = 1;
        while stage_directory(dir, k + 1).join(STAGE_PLAN_FILE).exists() {
            k += 1;
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body() -> StageBody {
        StageBody {
            study_plan_hash: "0123456789abcdef".to_string(),
            previous_stage_hash: "0123456789abcdef".to_string(),
            stage: 2,
            phase: "adaptive".to_string(),
            nominal: false,
            samples: 2,
            // 1e-7 is written `1e-7`: read as `1E-7` it is the same number, so only the check of
            // the whole text catches that flip.
            points_xi: vec![vec![0.5, -1.0], vec![1e-7, 0.25]],
            previous_blocks: vec![InputFile {
                path: PathBuf::from("shard-0-of-1.records.mcap"),
                fnv1a64: "00112233445566ff".to_string(),
            }],
        }
    }

    #[test]
    fn a_stage_plan_reads_back_and_an_edited_one_is_refused() {
        let dir = std::env::temp_dir().join(format!("ribbon-stage-plan-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("mkdir");
        let path = dir.join(STAGE_PLAN_FILE);
        let plan = StagePlanFile::new(body());
        std::fs::write(&path, plan.to_json()).expect("write");
        assert_eq!(
            StagePlanFile::read(&path, 2, "merge again").ok(),
            Some(plan.clone())
        );
        // Another body, another hash.
        let mut other = body();
        other.points_xi[1][1] = 0.5;
        assert_ne!(StagePlanFile::new(other).stage_hash, plan.stage_hash);
        // Points of the wrong dimension.
        let message = StagePlanFile::read(&path, 3, "merge again")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(message.contains("do not match"), "{message}");
        // An edited body no longer hashes to its stage_hash.
        let edited = plan.to_json().replacen("\"stage\": 2", "\"stage\": 3", 1);
        std::fs::write(&path, edited).expect("write");
        let message = StagePlanFile::read(&path, 2, "merge again")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(message.contains("edited"), "{message}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_stage_plan_with_any_bit_flipped_is_refused() {
        let dir = std::env::temp_dir().join(format!("ribbon-stage-flips-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("mkdir");
        let path = dir.join(STAGE_PLAN_FILE);
        let clean = StagePlanFile::new(body()).to_json().into_bytes();
        for i in 0..clean.len() {
            for bit in 0..8 {
                let mut flipped = clean.clone();
                flipped[i] ^= 1 << bit;
                std::fs::write(&path, &flipped).expect("write");
                match StagePlanFile::read(&path, 2, "REMEDY") {
                    Err(ShardError::Plan { message, .. }) => {
                        assert!(message.contains("REMEDY"), "byte {i} bit {bit}: {message}")
                    }
                    other => panic!("byte {i} bit {bit}: {other:?}"),
                }
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
