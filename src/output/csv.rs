//! CSV series: header `t`, then one column per output name; one row per record time. Names are
//! quoted as RFC 4180 asks when they hold a comma, a double quote or a line break (a quote inside is
//! doubled), so that any joint or link name survives a CSV reader. Values are written with Rust's
//! shortest round-trip formatting; a NaN or infinity is refused before anything is written.

use super::check_finite;
use super::error::OutputError;
use super::paths::AtomicFile;
use std::io::Write;
use std::path::Path;

/// One CSV field as RFC 4180 writes it: unchanged, or in double quotes with inner quotes doubled
/// when it holds a comma, a quote, CR or LF.
pub fn csv_field(text: &str) -> std::borrow::Cow<'_, str> {
    if text.contains([',', '"', '\n', '\r']) {
        std::borrow::Cow::Owned(format!("\"{}\"", text.replace('"', "\"\"")))
    } else {
        std::borrow::Cow::Borrowed(text)
    }
}

/// Writes `columns[i][k]` (output `i` at `times[k]`) under `names` to `path`, streaming through a
/// temporary file (see [`super::paths`]). Refuses a non-finite value, naming the column and time.
pub fn write_csv(
    path: &Path,
    times: &[f64],
    names: &[&str],
    columns: &[&[f64]],
) -> Result<(), OutputError> {
    check_finite(&format!("CSV '{}'", path.display()), names, times, columns)?;
    let mut file = AtomicFile::create(path, "CSV")?;
    let result = (|| -> std::io::Result<()> {
        file.write_all(b"t")?;
        for name in names {
            write!(file, ",{}", csv_field(name))?;
        }
        file.write_all(b"\n")?;
        for (k, t) in times.iter().enumerate() {
            write!(file, "{t}")?;
            for column in columns {
                write!(file, ",{}", column[k])?;
            }
            file.write_all(b"\n")?;
        }
        Ok(())
    })();
    result.map_err(|e| file.error(e))?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_quoted_as_rfc_4180_asks() {
        assert_eq!(csv_field("q.elbow_joint"), "q.elbow_joint");
        assert_eq!(csv_field("q.a,b"), "\"q.a,b\"");
        assert_eq!(csv_field("q.say \"hi\""), "\"q.say \"\"hi\"\"\"");
        assert_eq!(csv_field("q.two\nlines"), "\"q.two\nlines\"");
    }

    #[test]
    fn a_non_finite_value_is_refused_and_nothing_written() {
        let dir = std::env::temp_dir().join(format!("ribbon-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("nan.csv");
        let e = write_csv(
            &path,
            &[0.0, 0.5],
            &["q.a", "q.b"],
            &[&[1.0, 2.0], &[3.0, f64::NAN]],
        )
        .unwrap_err();
        assert_eq!(e.exit_code(), 1);
        let m = e.to_string();
        assert!(m.contains("output 'q.b' is NaN at t = 0.5 s"), "{m}");
        assert!(!path.exists());
        assert!(
            std::fs::read_dir(&dir).unwrap().next().is_none(),
            "no temporary left"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
