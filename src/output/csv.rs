//! CSV series: header `t`, then one column per output name; one row per record time.

use super::write_atomically;
use crate::Error;
use std::fmt::Write;
use std::path::Path;

/// Writes `columns[i][k]` (output `i` at `times[k]`) under `names` to `path`.
pub fn write_csv(
    path: &Path,
    times: &[f64],
    names: &[&str],
    columns: &[&[f64]],
) -> Result<(), Error> {
    let mut text = String::with_capacity(times.len() * (names.len() + 1) * 12);
    text.push('t');
    for name in names {
        text.push(',');
        text.push_str(name);
    }
    text.push('\n');
    for (k, t) in times.iter().enumerate() {
        let _ = write!(text, "{t}");
        for column in columns {
            let _ = write!(text, ",{}", column[k]);
        }
        text.push('\n');
    }
    write_atomically(path, "CSV", text.as_bytes())
}
