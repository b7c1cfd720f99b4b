//! One study across many machines (docs/distributed.md): `plan` writes the study's plan file (the
//! inputs' hashes, the options, the expanded box, the design's sample list, the record schedule);
//! `run` simulates one shard — a contiguous range of the design's samples, the first shard also the
//! nominal run — into a record block file; `merge` reads every shard's record block, block of
//! record times by block, as the design's values of the same stages `analyze` runs in one process
//! (fit, bound, the a-posteriori check, the chaos estimate, the sinks). The merged outputs are the
//! single-machine outputs bit for bit, for any number of shards and threads.

mod error;
mod hash;
mod plan_file;
mod record_block;
mod shards;

pub use error::ShardError;
pub use hash::{fnv1a64, fnv1a64_file};
pub use plan_file::{InputFile, PlanBody, PlanFile, PlanOptions, PLAN_FORMAT, PLAN_VERSION};
pub use record_block::{
    BlockHeader, BlockTrailer, RecordBlockReader, RecordBlockWriter, NOMINAL_TOPIC,
    RECORDS_ENCODING, RECORDS_TOPIC, RECORD_BLOCK_PROFILE, RECORD_BLOCK_VERSION,
};
pub use shards::{shard_file_name, ShardSet, ShardSpec, SHARD_INDEX_VARIABLES};
