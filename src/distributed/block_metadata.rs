//! The metadata records of a record block (docs/distributed.md §3): the header `ribbon.shard`
//! ([`BlockHeader`]: plan hash, shard K of N, samples, sizes), written before the data, and the
//! trailer `ribbon.shard.end` ([`BlockTrailer`]: complete, failures, counters), written after it.
//! MCAP metadata is string → string: counts as decimal text, flags as `true` | `false`, lists as
//! JSON; reading one back names the record and the key that is missing or wrong.

use crate::analysis::SampleFailure;
use crate::effects::ContactStats;
use std::collections::BTreeMap;

/// The version of the record block layout (the `format_version` metadata entry): 2 since the
/// trailer carries the digest of the bytes before it (version 1 had none).
pub const RECORD_BLOCK_VERSION: u32 = 2;
/// Name of the metadata record at the start.
pub(super) const HEADER_NAME: &str = "ribbon.shard";
/// Name of the metadata record at the end.
pub(super) const TRAILER_NAME: &str = "ribbon.shard.end";

/// What a record block holds, written before the data.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockHeader {
    /// The plan's hash.
    pub plan_hash: String,
    /// The shard's index, from 0.
    pub shard: usize,
    /// Shards in all.
    pub shards: usize,
    /// First design sample held.
    pub first_sample: usize,
    /// One past the last design sample held.
    pub end_sample: usize,
    /// Whether the block holds the nominal run (`/nominal`).
    pub nominal: bool,
    /// Outputs per record.
    pub outputs: usize,
    /// Record times.
    pub records: usize,
    /// Configuration coordinates (of the nominal run's positions).
    pub nq: usize,
}

impl BlockHeader {
    /// Design samples held.
    pub fn samples(&self) -> usize {
        self.end_sample - self.first_sample
    }

    pub(super) fn to_metadata(&self) -> BTreeMap<String, String> {
        [
            ("format_version", RECORD_BLOCK_VERSION.to_string()),
            ("plan_hash", self.plan_hash.clone()),
            ("shard", self.shard.to_string()),
            ("shards", self.shards.to_string()),
            ("first_sample", self.first_sample.to_string()),
            ("end_sample", self.end_sample.to_string()),
            ("nominal", self.nominal.to_string()),
            ("outputs", self.outputs.to_string()),
            ("records", self.records.to_string()),
            ("nq", self.nq.to_string()),
            (
                "layout",
                "/records: samples first_sample..end_sample × outputs; /nominal: outputs then nq positions; f64 little-endian, one message per record time".to_string(),
            ),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }

    pub(super) fn from_metadata(map: &BTreeMap<String, String>) -> Result<BlockHeader, String> {
        let text = |key: &str| {
            map.get(key)
                .cloned()
                .ok_or_else(|| format!("the ribbon.shard metadata has no '{key}'"))
        };
        let number = |key: &str| -> Result<usize, String> {
            text(key)?
                .parse()
                .map_err(|_| format!("ribbon.shard '{key}' is not a count"))
        };
        let version = number("format_version")?;
        if version != RECORD_BLOCK_VERSION as usize {
            return Err(format!(
                "record block version {version}, this ribbon reads version {RECORD_BLOCK_VERSION}"
            ));
        }
        let header = BlockHeader {
            plan_hash: text("plan_hash")?,
            shard: number("shard")?,
            shards: number("shards")?,
            first_sample: number("first_sample")?,
            end_sample: number("end_sample")?,
            nominal: flag(map, HEADER_NAME, "nominal")?,
            outputs: number("outputs")?,
            records: number("records")?,
            nq: number("nq")?,
        };
        if header.end_sample < header.first_sample {
            return Err("end_sample before first_sample".to_string());
        }
        Ok(header)
    }
}

/// What a record block says after the data: the persisted form of what simulating the shard did
/// ([`crate::analysis::DesignPart`], less its seconds, which would break byte identity). The two
/// stay apart because the analysis may not depend on the block format; a field the merge must
/// report goes into both.
#[derive(Clone, Debug)]
pub struct BlockTrailer {
    /// Whether every record time was written.
    pub complete: bool,
    /// Samples left out under `--keep-going` (indices in the whole design).
    pub failures: Vec<SampleFailure>,
    /// Samples re-run with the adaptive step, each with its fixed step's failure (indices in the
    /// whole design; the `retried` entry, absent when there are none).
    pub retried: Vec<SampleFailure>,
    /// Newton iterations of the shard's runs.
    pub newton_iterations: u64,
    /// Steps of the shard's runs.
    pub steps: u64,
    /// Contact counters of the shard's runs, summed (the `contacts` entry, absent when the scene
    /// declares no contacts), so that a merge reports what `analyze` reports.
    pub contacts: Option<ContactStats>,
}

impl BlockTrailer {
    pub(super) fn to_metadata(&self) -> BTreeMap<String, String> {
        let mut map: BTreeMap<String, String> = [
            ("complete", self.complete.to_string()),
            ("newton_iterations", self.newton_iterations.to_string()),
            ("steps", self.steps.to_string()),
            ("failures", failures_json(&self.failures)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        if !self.retried.is_empty() {
            map.insert("retried".to_string(), failures_json(&self.retried));
        }
        if let Some(contacts) = &self.contacts {
            // Counts as integers; the depth's shortest round-trip text reads back to the same f64.
            let entry = serde_json::json!({
                "pair_tests": contacts.pair_tests,
                "narrow_queries": contacts.narrow_queries,
                "made": contacts.made,
                "broken": contacts.broken,
                "max_depth_m": contacts.max_depth_m,
            });
            map.insert("contacts".to_string(), entry.to_string());
        }
        map
    }

    pub(super) fn from_metadata(map: &BTreeMap<String, String>) -> Result<BlockTrailer, String> {
        let text = |key: &str| {
            map.get(key)
                .ok_or_else(|| format!("the ribbon.shard.end metadata has no '{key}'"))
        };
        let count = |key: &str| -> Result<u64, String> {
            text(key)?
                .parse()
                .map_err(|_| format!("ribbon.shard.end '{key}' is not a count"))
        };
        let failures = failures_from_json(text("failures")?, "failures")?;
        let retried = match map.get("retried") {
            Some(entry) => failures_from_json(entry, "retried")?,
            None => Vec::new(),
        };
        let contacts = match map.get("contacts") {
            None => None,
            Some(entry) => {
                let value: serde_json::Value = serde_json::from_str(entry)
                    .map_err(|e| format!("ribbon.shard.end 'contacts' is not JSON: {e}"))?;
                let count = |key: &str| {
                    value
                        .get(key)
                        .and_then(serde_json::Value::as_u64)
                        .ok_or_else(|| {
                            format!("ribbon.shard.end 'contacts' lacks the count '{key}'")
                        })
                };
                Some(ContactStats {
                    pair_tests: count("pair_tests")?,
                    narrow_queries: count("narrow_queries")?,
                    made: count("made")?,
                    broken: count("broken")?,
                    max_depth_m: value
                        .get("max_depth_m")
                        .and_then(serde_json::Value::as_f64)
                        .ok_or("ribbon.shard.end 'contacts' lacks 'max_depth_m'")?,
                })
            }
        };
        Ok(BlockTrailer {
            complete: flag(map, TRAILER_NAME, "complete")?,
            failures,
            retried,
            newton_iterations: count("newton_iterations")?,
            steps: count("steps")?,
            contacts,
        })
    }
}

/// A list of sample failures as the trailer's JSON (`failures`, `retried`).
fn failures_json(failures: &[SampleFailure]) -> String {
    let entries: Vec<serde_json::Value> = failures
        .iter()
        .map(|f| {
            serde_json::json!({
                "index": f.index, "xi": f.xi, "values": f.values, "time_s": f.time_s,
                "record": f.record, "message": f.message,
            })
        })
        .collect();
    serde_json::Value::Array(entries).to_string()
}

/// The trailer's list `key` of sample failures, read back from its JSON `text`.
fn failures_from_json(text: &str, key: &str) -> Result<Vec<SampleFailure>, String> {
    let entries: Vec<serde_json::Value> = serde_json::from_str(text)
        .map_err(|e| format!("ribbon.shard.end '{key}' is not a JSON list: {e}"))?;
    entries
        .iter()
        .map(|f| {
            let floats = |key: &str| -> Option<Vec<f64>> {
                f.get(key)?.as_array()?.iter().map(|x| x.as_f64()).collect()
            };
            Some(SampleFailure {
                index: usize::try_from(f.get("index")?.as_u64()?).ok()?,
                xi: floats("xi")?,
                values: floats("values")?,
                time_s: f.get("time_s")?.as_f64()?,
                record: usize::try_from(f.get("record")?.as_u64()?).ok()?,
                message: f.get("message")?.as_str()?.to_string(),
            })
        })
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| format!("an entry of '{key}' in ribbon.shard.end lacks a field"))
}

/// The entry `key` of the metadata `record` as a boolean: `true` or `false`, nothing else.
fn flag(map: &BTreeMap<String, String>, record: &str, key: &str) -> Result<bool, String> {
    match map.get(key).map(String::as_str) {
        Some("true") => Ok(true),
        Some("false") => Ok(false),
        Some(other) => Err(format!("{record} '{key}' is '{other}', not true or false")),
        None => Err(format!("the {record} metadata has no '{key}'")),
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A complete trailer with small counters and `contacts`.
    pub(in crate::distributed) fn trailer(contacts: Option<ContactStats>) -> BlockTrailer {
        BlockTrailer {
            complete: true,
            failures: Vec::new(),
            retried: Vec::new(),
            newton_iterations: 7,
            steps: 5,
            contacts,
        }
    }

    #[test]
    fn contact_counters_round_trip_through_the_trailer() {
        let counters = ContactStats {
            pair_tests: 956_864,
            narrow_queries: 606_088,
            made: 910,
            broken: 546,
            max_depth_m: 0.004_642_133_472_520_491,
        };
        let map = trailer(Some(counters)).to_metadata();
        let read = BlockTrailer::from_metadata(&map).unwrap();
        assert_eq!(read.contacts, Some(counters));
        // Without contacts the entry is absent, and reads back as none.
        let map = trailer(None).to_metadata();
        assert!(!map.contains_key("contacts"));
        assert_eq!(BlockTrailer::from_metadata(&map).unwrap().contacts, None);
    }

    #[test]
    fn a_malformed_contacts_entry_is_named() {
        let mut map = trailer(None).to_metadata();
        map.insert("contacts".to_string(), "{not json".to_string());
        let message = BlockTrailer::from_metadata(&map).unwrap_err();
        assert!(message.contains("'contacts' is not JSON"), "{message}");
        map.insert(
            "contacts".to_string(),
            r#"{"pair_tests": 1, "narrow_queries": 1, "made": 1, "max_depth_m": 0.0}"#.to_string(),
        );
        let message = BlockTrailer::from_metadata(&map).unwrap_err();
        assert!(message.contains("lacks the count 'broken'"), "{message}");
    }
}
