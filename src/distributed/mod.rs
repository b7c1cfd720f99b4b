//! One study across many machines (docs/distributed.md): `plan` writes the study's plan file (the
//! inputs' hashes, the options, the expanded box, the design's sample list, the record schedule);
//! `run` simulates one shard — a contiguous range of the design's samples, the first shard also the
//! nominal run — into a record block file; `merge` reads every shard's record block, block of
//! record times by block, as the design's values of the same stages `analyze` runs in one process
//! (fit, bound, the a-posteriori check, the chaos estimate, the sinks). The merged outputs are the
//! single-machine outputs bit for bit, for any number of shards and threads. Designs that choose
//! runs from earlier runs (screened, adaptive) run in stages: each `merge` replays the stages
//! whose records exist and plans the next one, until the last merge writes the outputs.

mod block_metadata;
mod error;
mod hash;
mod integrity;
mod plan_file;
mod record_block;
mod shards;
mod stage_plan;
mod stage_records;

pub use block_metadata::{BlockHeader, BlockTrailer, RECORD_BLOCK_VERSION};
pub use error::ShardError;
pub use hash::{fnv1a64, fnv1a64_file, Fnv1a64};
pub use plan_file::{
    InputFile, PlanBody, PlanFile, PlanOptions, StagedDesign, PLAN_FORMAT, PLAN_VERSION,
};
pub use record_block::{
    RecordBlockReader, RecordBlockWriter, NOMINAL_TOPIC, RECORDS_ENCODING, RECORDS_TOPIC,
    RECORD_BLOCK_PROFILE,
};
pub use shards::{shard_file_name, ShardSet, ShardSpec, SHARD_INDEX_VARIABLES};
pub use stage_plan::{
    stage_directory, Stage, StageBody, StagePlanFile, STAGE_PLAN_FILE, STAGE_PLAN_FORMAT,
    STAGE_PLAN_VERSION,
};
pub use stage_records::ShardStages;

/// The exit status of a `merge` that planned (or found pending) another stage instead of writing
/// the outputs: run the stage's shards, then merge again (docs/distributed.md §7).
pub const NEXT_STAGE_EXIT_CODE: u8 = 3;
