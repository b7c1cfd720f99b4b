//! Which samples a shard runs, and the set of shards a merge reads as the design's records.

use super::error::ShardError;
use super::plan_file::{InputFile, PlanFile};
use super::record_block::RecordBlockReader;
use super::stage_plan::Stage;
use crate::analysis::{BlockOutcome, ForeignError, RecordSource, SampleFailure, StudyError};
use crate::effects::ContactStats;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// Environment variables that give a shard its index when `--shard` does not, in the order they
/// are tried: Slurm job arrays, then Kubernetes Indexed Jobs. Both count from 0 (submit Slurm
/// arrays as `--array=0-(N-1)`).
pub const SHARD_INDEX_VARIABLES: [&str; 2] = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"];

/// Shard `index` of `count` (from 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShardSpec {
    /// The shard's index, `0..count`.
    pub index: usize,
    /// Shards in all.
    pub count: usize,
}

impl ShardSpec {
    /// Parses `--shard K/N` (K from 0).
    pub fn parse(text: &str) -> Result<ShardSpec, ShardError> {
        let bad = |message: String| ShardError::BadShard {
            flag: "--shard".to_string(),
            message,
        };
        let (k, n) = text.split_once('/').ok_or_else(|| {
            bad(format!(
                "'{text}' is not K/N; give the shard index (from 0) and the shard count, e.g. --shard 0/4, or --shards N to read K from {}",
                SHARD_INDEX_VARIABLES.join(" or ")
            ))
        })?;
        let parse = |s: &str, what: &str| {
            s.trim()
                .parse::<usize>()
                .map_err(|_| bad(format!("'{s}' in '{text}' is not a {what}")))
        };
        ShardSpec::new(
            parse(k, "shard index")?,
            parse(n, "shard count")?,
            "--shard",
        )
    }

    /// Shard K of `count`, K read from the first of [`SHARD_INDEX_VARIABLES`] that is set (via
    /// `lookup`, normally `std::env::var`).
    pub fn from_environment(
        count: usize,
        lookup: &dyn Fn(&str) -> Option<String>,
    ) -> Result<ShardSpec, ShardError> {
        for variable in SHARD_INDEX_VARIABLES {
            if let Some(value) = lookup(variable) {
                let index = value
                    .trim()
                    .parse::<usize>()
                    .map_err(|_| ShardError::BadShard {
                        flag: variable.to_string(),
                        message: format!("'{value}' is not a shard index"),
                    })?;
                if variable == "SLURM_ARRAY_TASK_ID" {
                    if let Some(min) = lookup("SLURM_ARRAY_TASK_MIN") {
                        if min.trim() != "0" {
                            return Err(ShardError::BadShard {
                                flag: variable.to_string(),
                                message: format!(
                                    "the array starts at {min}, but ribbon counts shards from 0: submit with --array=0-{}",
                                    count.saturating_sub(1)
                                ),
                            });
                        }
                    }
                }
                return ShardSpec::new(index, count, variable);
            }
        }
        Err(ShardError::BadShard {
            flag: "--shards".to_string(),
            message: format!(
                "no shard index: give --shard K/N, or run under a scheduler that sets {}",
                SHARD_INDEX_VARIABLES.join(" or ")
            ),
        })
    }

    fn new(index: usize, count: usize, flag: &str) -> Result<ShardSpec, ShardError> {
        if count == 0 || index >= count {
            return Err(ShardError::BadShard {
                flag: flag.to_string(),
                message: format!(
                    "shard {index} of {count}: shards are counted from 0, so the index must be in 0..{count} (0 to {}) and the count at least 1",
                    count.saturating_sub(1)
                ),
            });
        }
        Ok(ShardSpec { index, count })
    }

    /// The design samples of this shard among `samples`: a contiguous range, the ranges of
    /// consecutive shards adjacent, their sizes differing by at most one.
    pub fn samples(&self, samples: usize) -> Range<usize> {
        let at = |k: usize| k * samples / self.count;
        at(self.index)..at(self.index + 1)
    }

    /// Whether this shard also runs the nominal run (shard 0).
    pub fn runs_nominal(&self) -> bool {
        self.index == 0
    }
}

/// The file name of shard K of N in its directory.
pub fn shard_file_name(spec: ShardSpec) -> String {
    format!("shard-{}-of-{}.records.mcap", spec.index, spec.count)
}

/// The record blocks of every shard of a plan, read together as the design's records: one block
/// of record times of every sample at a time (the same blocks `analyze` simulates), so that
/// memory holds one block, as in a single-machine study.
pub struct ShardSet {
    readers: Vec<RecordBlockReader>,
    samples: usize,
    /// Whether the set holds the nominal run (after the samples).
    nominal: bool,
    outputs: usize,
    nq: usize,
    /// The current block: per record, `(samples + 1) × outputs` (the nominal run last).
    block: Vec<Vec<f64>>,
    /// The nominal run's configuration per record of the block.
    positions: Vec<Vec<f64>>,
    /// Every shard's failures, by sample index.
    failures: Vec<SampleFailure>,
    /// Every shard's samples re-run with the adaptive step (their fixed step's failures), by
    /// sample index.
    retried: Vec<SampleFailure>,
    /// One past the last record of the current block.
    end: usize,
    counters: (u64, u64),
    /// Every shard's contact counters, merged; `None` without contacts.
    contacts: Option<ContactStats>,
    /// Every block opened (empty shards included), by file name, with its digest.
    blocks: Vec<InputFile>,
}

impl ShardSet {
    /// Opens every record block in `dir` (files named `shard-K-of-N.records.mcap`) and checks that
    /// they belong to `plan` (read from `plan_path`) and tile its samples exactly once, with one
    /// nominal run. Names the missing, duplicated, foreign, truncated and corrupted ones.
    pub fn open(plan: &PlanFile, plan_path: &Path, dir: &Path) -> Result<ShardSet, ShardError> {
        ShardSet::open_stage(plan, &Stage::first(plan, plan_path, dir))
    }

    /// The record block files of `dir` (`shard-K-of-N.records.mcap`), sorted; none when the
    /// directory does not exist.
    pub fn block_files(dir: &Path) -> Result<Vec<PathBuf>, ShardError> {
        let io = |source| ShardError::Io {
            what: "list the shard directory",
            path: dir.to_path_buf(),
            source,
        };
        let entries = match std::fs::read_dir(dir) {
            Ok(entries) => entries,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
            Err(e) => return Err(io(e)),
        };
        let mut paths: Vec<PathBuf> = entries
            .map(|entry| entry.map(|e| e.path()))
            .collect::<Result<_, _>>()
            .map_err(io)?;
        paths.retain(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("shard-") && n.ends_with(".records.mcap"))
        });
        paths.sort();
        Ok(paths)
    }

    /// [`ShardSet::open`] for one stage of `plan` (docs/distributed.md §7): the record blocks in
    /// `stage.directory`, which must carry the stage's hash (a block of another stage or study
    /// is foreign) and tile its samples exactly once, with the nominal run where the stage has
    /// one.
    pub fn open_stage(plan: &PlanFile, stage: &Stage) -> Result<ShardSet, ShardError> {
        let dir = stage.directory.as_path();
        let paths = ShardSet::block_files(dir)?;
        let body = &plan.body;
        let mut readers = Vec::with_capacity(paths.len());
        for path in &paths {
            let reader = RecordBlockReader::open(path, &stage.run_command(path))?;
            let header = reader.header();
            if header.plan_hash != stage.hash {
                return Err(ShardError::Foreign {
                    path: path.clone(),
                    found: header.plan_hash.clone(),
                    expected: stage.hash.clone(),
                });
            }
            let expected = (body.outputs.len(), body.records, body.nq);
            if (header.outputs, header.records, header.nq) != expected
                || header.end_sample > stage.samples
                || (header.nominal && !stage.nominal)
            {
                return Err(ShardError::Malformed {
                    path: path.clone(),
                    message: format!(
                        "its sizes (outputs, records, nq) = {:?}, samples ..{} and nominal run {} do not fit the stage's {expected:?}, {} samples and nominal run {}",
                        (header.outputs, header.records, header.nq),
                        header.end_sample,
                        header.nominal,
                        stage.samples,
                        stage.nominal
                    ),
                });
            }
            readers.push(reader);
        }
        readers.sort_by_key(|r| (r.header().first_sample, r.header().end_sample));
        check_tiling(&readers, stage.samples, stage.nominal, dir)?;
        let mut blocks: Vec<InputFile> = readers
            .iter()
            .map(|r| InputFile {
                path: PathBuf::from(r.path().file_name().unwrap_or_default()),
                fnv1a64: r.block_digest().to_string(),
            })
            .collect();
        blocks.sort_by(|a, b| a.path.cmp(&b.path));
        // Empty shards (more shards than samples) hold no samples: keep only those with data
        // or the nominal run.
        readers.retain(|r| r.header().samples() > 0 || r.header().nominal);
        let mut failures: Vec<SampleFailure> = readers
            .iter()
            .flat_map(|r| r.trailer().failures.iter().cloned())
            .collect();
        failures.sort_by_key(|f| f.index);
        let mut retried: Vec<SampleFailure> = readers
            .iter()
            .flat_map(|r| r.trailer().retried.iter().cloned())
            .collect();
        retried.sort_by_key(|f| f.index);
        let counters = readers.iter().fold((0, 0), |(n, s), r| {
            (n + r.trailer().newton_iterations, s + r.trailer().steps)
        });
        let contacts =
            readers
                .iter()
                .filter_map(|r| r.trailer().contacts)
                .reduce(|mut all, shard| {
                    all.merge(&shard);
                    all
                });
        Ok(ShardSet {
            readers,
            samples: stage.samples,
            nominal: stage.nominal,
            outputs: body.outputs.len(),
            nq: body.nq,
            block: Vec::new(),
            positions: Vec::new(),
            failures,
            retried,
            end: 0,
            counters,
            contacts,
            blocks,
        })
    }

    /// The record block files read, in sample order.
    pub fn files(&self) -> Vec<&Path> {
        self.readers.iter().map(|r| r.path()).collect()
    }

    /// Every record block read, by file name, with the FNV-1a 64 of its bytes, in file name
    /// order: what the plan of the next stage names as the records it was planned from.
    pub fn block_digests(&self) -> &[InputFile] {
        &self.blocks
    }
}

/// Refuses overlapping ranges (duplicated shards), gaps (missing ones), and anything but one
/// nominal run.
fn check_tiling(
    readers: &[RecordBlockReader],
    samples: usize,
    with_nominal: bool,
    dir: &Path,
) -> Result<(), ShardError> {
    let mut covered = 0;
    let mut missing: Vec<String> = Vec::new();
    let mut last: Option<&RecordBlockReader> = None;
    for reader in readers {
        let h = reader.header();
        if let Some(previous) = last {
            let p = previous.header();
            let overlap = h.first_sample < p.end_sample
                || (h.samples() == 0
                    && p.samples() == 0
                    && h.first_sample == p.first_sample
                    && h.nominal
                    && p.nominal);
            if overlap {
                return Err(ShardError::Duplicated {
                    first: previous.path().to_path_buf(),
                    second: reader.path().to_path_buf(),
                    start: h.first_sample,
                    end: h.end_sample.min(p.end_sample),
                    nominal: h.nominal && p.nominal,
                });
            }
        }
        if h.first_sample > covered {
            missing.push(format!("samples {covered}..{}", h.first_sample));
        }
        covered = covered.max(h.end_sample);
        last = Some(reader);
    }
    if covered < samples {
        missing.push(format!("samples {covered}..{samples}"));
    }
    let nominal: Vec<&RecordBlockReader> = readers.iter().filter(|r| r.header().nominal).collect();
    if nominal.len() > 1 {
        return Err(ShardError::Duplicated {
            first: nominal[0].path().to_path_buf(),
            second: nominal[1].path().to_path_buf(),
            start: 0,
            end: 0,
            nominal: true,
        });
    }
    if nominal.is_empty() && with_nominal {
        missing.push("the nominal run (shard 0)".to_string());
    }
    if !missing.is_empty() {
        let counts: Vec<usize> = readers.iter().map(|r| r.header().shards).collect();
        let shards = match counts.first() {
            Some(&n) if counts.iter().all(|&c| c == n) => {
                let present: Vec<usize> = readers.iter().map(|r| r.header().shard).collect();
                let absent: Vec<String> = (0..n)
                    .filter(|k| !present.contains(k))
                    .map(|k| format!("shard-{k}-of-{n}"))
                    .collect();
                absent.join(", ")
            }
            _ => "`ribbon run PLAN --shard K/N --into DIR` for each missing K".to_string(),
        };
        return Err(ShardError::Missing {
            dir: dir.to_path_buf(),
            missing: missing.join(", "),
            shards,
        });
    }
    Ok(())
}

impl RecordSource for ShardSet {
    fn len(&self) -> usize {
        self.samples + usize::from(self.nominal)
    }

    fn nominal_index(&self) -> Option<usize> {
        self.nominal.then_some(self.samples)
    }

    fn advance(
        &mut self,
        first: usize,
        count: usize,
        _threads: &rayon::ThreadPool,
        _interrupt: &AtomicBool,
    ) -> Result<BlockOutcome, StudyError> {
        let width = self.len() * self.outputs;
        self.block.resize_with(count, Vec::new);
        self.positions.resize_with(count, Vec::new);
        let (outputs, nq) = (self.outputs, self.nq);
        for (row, positions) in self.block.iter_mut().zip(&mut self.positions) {
            row.resize(width, 0.0);
            positions.resize(nq, 0.0);
        }
        let mut nominal = vec![0.0; outputs + nq];
        for r in 0..count {
            for reader in &mut self.readers {
                let h = reader.header();
                let range = h.first_sample * outputs..h.end_sample * outputs;
                let has_nominal = h.nominal;
                let row = &mut self.block[r];
                let target = has_nominal.then_some(nominal.as_mut_slice());
                reader
                    .read_record(&mut row[range], target)
                    .map_err(|e| StudyError::Records(ForeignError::new(e)))?;
                if has_nominal {
                    row[self.samples * outputs..].copy_from_slice(&nominal[..outputs]);
                    self.positions[r].copy_from_slice(&nominal[outputs..]);
                }
            }
        }
        self.end = first + count;
        Ok(BlockOutcome::Complete)
    }

    fn record(&self, i: usize, r: usize) -> &[f64] {
        &self.block[r][i * self.outputs..(i + 1) * self.outputs]
    }

    fn nominal_positions(&self, r: usize) -> &[f64] {
        self.positions.get(r).map_or(&[][..], Vec::as_slice)
    }

    fn failed(&self, i: usize) -> bool {
        self.failures
            .iter()
            .any(|f| f.index == i && f.record < self.end)
    }

    fn failures(&self) -> Vec<SampleFailure> {
        reached(&self.failures, self.end)
    }

    fn retries(&self) -> Vec<SampleFailure> {
        reached(&self.retried, self.end)
    }

    fn counters(&self) -> (u64, u64) {
        self.counters
    }

    fn contact_counters(&self) -> Option<ContactStats> {
        self.contacts
    }
}

/// The entries of `list` whose record is before `end` (the records read so far).
fn reached(list: &[SampleFailure], end: usize) -> Vec<SampleFailure> {
    list.iter().filter(|f| f.record < end).cloned().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_tile_the_samples() {
        for samples in [0, 1, 5, 26, 1001] {
            for count in 1..9 {
                let mut next = 0;
                for index in 0..count {
                    let range = ShardSpec { index, count }.samples(samples);
                    assert_eq!(range.start, next);
                    assert!(range.len() <= samples.div_ceil(count));
                    next = range.end;
                }
                assert_eq!(next, samples);
            }
        }
    }

    #[test]
    fn shard_flags_and_variables() {
        assert_eq!(
            ShardSpec::parse("2/7").ok(),
            Some(ShardSpec { index: 2, count: 7 })
        );
        assert!(ShardSpec::parse("7/7").is_err());
        assert!(ShardSpec::parse("3").is_err());
        assert!(ShardSpec::parse("0/0").is_err());
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| {
                pairs
                    .iter()
                    .find(|(n, _)| *n == k)
                    .map(|(_, v)| v.to_string())
            }
        };
        let slurm = env(&[("SLURM_ARRAY_TASK_ID", "3"), ("SLURM_ARRAY_TASK_MIN", "0")]);
        assert_eq!(
            ShardSpec::from_environment(4, &slurm).ok(),
            Some(ShardSpec { index: 3, count: 4 })
        );
        let one_based = env(&[("SLURM_ARRAY_TASK_ID", "4"), ("SLURM_ARRAY_TASK_MIN", "1")]);
        let message = ShardSpec::from_environment(4, &one_based)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(message.contains("--array=0-3"), "{message}");
        let k8s = env(&[("JOB_COMPLETION_INDEX", "1")]);
        assert_eq!(
            ShardSpec::from_environment(2, &k8s).ok(),
            Some(ShardSpec { index: 1, count: 2 })
        );
        assert!(ShardSpec::from_environment(2, &env(&[])).is_err());
    }
}
