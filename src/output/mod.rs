//! Sinks for results: CSV series, the summary JSON of the design contract, MCAP logs for Foxglove and
//! rerun ([`mcap`]). Every file is written to a
//! temporary name beside its target and renamed when complete, so a failure never leaves a corrupt
//! output file.

mod csv;
mod envelope_log;
pub mod mcap;
mod summary;
pub mod svg;

pub use csv::write_csv;
pub use envelope_log::EnvelopeLog;
pub use summary::{EnvelopeSeries, ParameterSummary, Summary};

use crate::Error;
use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` through `path.tmp` and a rename.
pub fn write_atomically(path: &Path, what: &str, bytes: &[u8]) -> Result<(), Error> {
    let mut temporary = path.as_os_str().to_owned();
    temporary.push(".tmp");
    let temporary = std::path::PathBuf::from(temporary);
    let fail = |source| Error::Output {
        what: format!("{what} '{}'", path.display()),
        source,
    };
    let result = std::fs::File::create(&temporary)
        .and_then(|mut file| file.write_all(bytes).and_then(|_| file.sync_all()))
        .and_then(|_| std::fs::rename(&temporary, path));
    if let Err(source) = result {
        let _ = std::fs::remove_file(&temporary);
        return Err(fail(source));
    }
    Ok(())
}
