//! The plan file (`study.plan`, JSON; docs/distributed.md §2): what every shard and the merge
//! must agree on, fingerprinted by the hash of its body.

use super::error::ShardError;
use super::hash::{fnv1a64, fnv1a64_file};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The `format` field of a plan file.
pub const PLAN_FORMAT: &str = "ribbon-study-plan";
/// The version of the plan format this build writes and reads.
pub const PLAN_VERSION: u32 = 1;

/// An input file of the plan, by path (as given to `plan`, relative to the working directory of
/// `run` and `merge`) and content hash.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InputFile {
    /// The path as given.
    pub path: PathBuf,
    /// FNV-1a 64 of its bytes, 16 lowercase hex digits.
    pub fnv1a64: String,
}

impl InputFile {
    /// Fingerprints the file at `path`.
    pub fn of(path: &Path) -> Result<InputFile, ShardError> {
        let hash = fnv1a64_file(path).map_err(|source| ShardError::Io {
            what: "read",
            path: path.to_path_buf(),
            source,
        })?;
        Ok(InputFile {
            path: path.to_path_buf(),
            fnv1a64: format!("{hash:016x}"),
        })
    }

    /// Refuses a file whose content is no longer the one planned (`what`: "URDF", "sidecar").
    pub fn check(&self, plan: &Path, what: &'static str) -> Result<(), ShardError> {
        let now = InputFile::of(&self.path)?;
        if now.fnv1a64 != self.fnv1a64 {
            return Err(ShardError::InputChanged {
                plan: plan.to_path_buf(),
                what,
                path: self.path.clone(),
                expected: self.fnv1a64.clone(),
                found: now.fnv1a64,
            });
        }
        Ok(())
    }
}

/// The `analyze` options the plan was made with (`None`: not given, the sidecar's `[analysis]` or
/// the default applies, exactly as for `analyze`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PlanOptions {
    /// `--duration`, s.
    pub duration: Option<f64>,
    /// `--step`, s.
    pub step: Option<f64>,
    /// `--alpha`.
    pub alpha: Option<f64>,
    /// `--floating`.
    pub floating: bool,
    /// `--method`.
    pub method: Option<String>,
    /// `--order`.
    pub order: Option<usize>,
    /// `--design`.
    pub design: Option<String>,
    /// `--grid`.
    pub grid: Option<usize>,
    /// `--scan-grid`.
    pub scan_grid: Option<usize>,
    /// `--samples`.
    pub samples: Option<usize>,
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--keep-going`.
    pub keep_going: bool,
    /// `--max-runs`.
    pub max_runs: Option<usize>,
    /// `--check-runs`.
    pub check_runs: Option<usize>,
    /// `--elements` (absent when not given, so that earlier plans hash as before).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elements: Option<String>,
    /// `--max-elements` (absent when not given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_elements: Option<usize>,
}

/// Everything the plan fixes; its canonical JSON is what the plan hash covers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanBody {
    /// The robot.
    pub urdf: InputFile,
    /// The sidecar.
    pub sidecar: InputFile,
    /// The options.
    pub options: PlanOptions,
    /// The method that runs (`auto` resolved).
    pub method: String,
    /// The design's name.
    pub design: String,
    /// Names of the box's dimensions, in order.
    pub parameters: Vec<String>,
    /// Names of the recorded outputs, in order.
    pub outputs: Vec<String>,
    /// Configuration coordinates of the model (the nominal run's positions per record).
    pub nq: usize,
    /// Steps of the horizon.
    pub n_steps: usize,
    /// Steps between records.
    pub record_every: usize,
    /// The step, s.
    pub step_s: f64,
    /// Record times (t = 0 and the last step included).
    pub records: usize,
    /// Design samples (the nominal run not counted).
    pub samples: usize,
    /// The samples' points in standard coordinates ξ ∈ [-1, 1]^d, one row per sample.
    pub points_xi: Vec<Vec<f64>>,
    /// The nominal run's point, named (it is not one of the samples).
    pub nominal_xi: Vec<f64>,
    /// Most runs the a-posteriori check adds at merge time.
    pub check_runs: usize,
    /// Designs that choose runs from earlier runs (screened, adaptive): the study runs in stages
    /// and `samples`/`points_xi` are those of stage 1; `merge` plans the later ones
    /// (docs/distributed.md §7). Absent for fixed designs (their plans hash as before).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub staged: Option<StagedDesign>,
}

/// What a plan of a staged design says about its first stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StagedDesign {
    /// The phase of stage 1: `screening` (screened designs) or `adaptive` (round 0).
    pub phase: String,
    /// Whether stage 1's first shard also runs the nominal run.
    pub nominal: bool,
}

/// A plan file: its format, version, hash and body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanFile {
    /// [`PLAN_FORMAT`].
    pub format: String,
    /// [`PLAN_VERSION`].
    pub version: u32,
    /// FNV-1a 64 of the body's canonical JSON, 16 lowercase hex digits: the plan's identity,
    /// written into every record block.
    pub plan_hash: String,
    /// The plan.
    pub body: PlanBody,
}

impl PlanFile {
    /// A plan file around `body`, with its hash.
    pub fn new(body: PlanBody) -> PlanFile {
        PlanFile {
            format: PLAN_FORMAT.to_string(),
            version: PLAN_VERSION,
            plan_hash: hash_of(&body),
            body,
        }
    }

    /// The plan file as JSON text (pretty, ending in a newline).
    pub fn to_json(&self) -> String {
        let mut text = serde_json::to_string_pretty(self).unwrap_or_default();
        text.push('\n');
        text
    }

    /// Reads and checks a plan file: its format, version and hash (an edited plan is refused), and
    /// that its text is byte for byte the one this ribbon writes for its content (a damaged byte
    /// anywhere, even one the parse would forgive, is refused).
    pub fn read(path: &Path) -> Result<PlanFile, ShardError> {
        let bad = |message: String| ShardError::Plan {
            path: path.to_path_buf(),
            message,
        };
        let bytes = std::fs::read(path).map_err(|source| ShardError::Io {
            what: "read the plan",
            path: path.to_path_buf(),
            source,
        })?;
        let text = String::from_utf8(bytes).map_err(|e| {
            bad(format!(
                "byte {} is not UTF-8 text: it was damaged; {REMAKE}",
                e.utf8_error().valid_up_to()
            ))
        })?;
        let value: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| bad(format!("not JSON ({e}); {REMAKE}")))?;
        if value.get("format").and_then(|f| f.as_str()) != Some(PLAN_FORMAT) {
            return Err(bad(format!(
                "not a ribbon plan (no \"format\": \"{PLAN_FORMAT}\"); make one with `ribbon plan ROBOT.urdf … --plan FILE`"
            )));
        }
        let version = value.get("version").and_then(|v| v.as_u64());
        if version != Some(u64::from(PLAN_VERSION)) {
            return Err(bad(format!(
                "plan format version {version:?}, this ribbon reads version {PLAN_VERSION}; make the plan again with this ribbon (`ribbon plan`), and run its shards again"
            )));
        }
        let plan: PlanFile =
            serde_json::from_value(value).map_err(|e| bad(format!("{e}; {REMAKE}")))?;
        let hash = hash_of(&plan.body);
        if hash != plan.plan_hash {
            return Err(bad(format!(
                "its body hashes to {hash}, not the {} it records: the plan was edited or damaged; {REMAKE}",
                plan.plan_hash
            )));
        }
        if let Some(at) = first_difference(&text, &plan.to_json()) {
            return Err(bad(format!(
                "its text differs at byte {at} from the text ribbon writes for its content: it was edited or damaged; {REMAKE}"
            )));
        }
        let d = plan.body.parameters.len();
        if plan.body.points_xi.len() != plan.body.samples
            || plan.body.points_xi.iter().any(|p| p.len() != d)
            || plan.body.nominal_xi.len() != d
        {
            return Err(bad(format!(
                "{} samples of {d} parameters declared, but the points do not match; {REMAKE}",
                plan.body.samples
            )));
        }
        Ok(plan)
    }

    /// The design's points, row-major `samples × d`.
    pub fn points(&self) -> Vec<f64> {
        self.body.points_xi.iter().flatten().copied().collect()
    }
}

/// What to do about a refused plan file.
const REMAKE: &str = "make it again with the `ribbon plan` command that made it (the same inputs and options give the same plan and hash, so the record blocks already run stay valid)";

/// The first byte at which `found` differs from `expected` (a shorter text differs where it
/// ends), or `None` when they are equal.
pub(super) fn first_difference(found: &str, expected: &str) -> Option<usize> {
    let (found, expected) = (found.as_bytes(), expected.as_bytes());
    let common = found
        .iter()
        .zip(expected)
        .take_while(|(a, b)| a == b)
        .count();
    (common < found.len().max(expected.len())).then_some(common)
}

/// FNV-1a 64 of the body's canonical (compact, field-ordered) JSON.
fn hash_of(body: &PlanBody) -> String {
    let canonical = serde_json::to_string(body).unwrap_or_default();
    format!("{:016x}", fnv1a64(canonical.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan() -> PlanFile {
        let input = |path: &str| InputFile {
            path: PathBuf::from(path),
            fnv1a64: "0123456789abcdef".to_string(),
        };
        PlanFile::new(PlanBody {
            urdf: input("robots/x.urdf"),
            sidecar: input("robots/x.uncertainty.toml"),
            options: PlanOptions {
                duration: Some(0.5),
                ..PlanOptions::default()
            },
            method: "legendre-scan".to_string(),
            design: "tensor".to_string(),
            parameters: vec!["l1".to_string()],
            outputs: vec!["q.j1".to_string()],
            nq: 1,
            n_steps: 500,
            record_every: 10,
            step_s: 0.001,
            records: 51,
            samples: 2,
            // 1e-7 is written `1e-7`; `1E-7` parses to the same number.
            points_xi: vec![vec![-0.5], vec![1e-7]],
            nominal_xi: vec![0.0],
            check_runs: 1,
            staged: None,
        })
    }

    #[test]
    fn a_plan_with_any_bit_flipped_is_refused() {
        let dir = std::env::temp_dir().join(format!("ribbon-plan-flips-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("mkdir");
        let path = dir.join("study.plan");
        let clean = plan().to_json().into_bytes();
        std::fs::write(&path, &clean).expect("write");
        assert_eq!(PlanFile::read(&path).ok(), Some(plan()));
        for i in 0..clean.len() {
            for bit in 0..8 {
                let mut flipped = clean.clone();
                flipped[i] ^= 1 << bit;
                std::fs::write(&path, &flipped).expect("write");
                match PlanFile::read(&path) {
                    Err(ShardError::Plan { message, .. }) => {
                        assert!(
                            message.contains("ribbon plan"),
                            "byte {i} bit {bit}: {message}"
                        )
                    }
                    other => panic!("byte {i} bit {bit}: {other:?}"),
                }
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
