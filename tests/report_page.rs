//! The report page for the browser (`ribbon analyze --report DIR` → `DIR/index.html`, issue 42
//! item 2), opened in a real headless Chromium with the network cut off
//! (`tests/reference/report_page.mjs`, through playwright-core): no console message of type error
//! or warning, no page error, no request beyond the page's own file, every picture drawn (an
//! inline SVG that decodes as an image and paints more than [`MIN_PAINTED_FRACTION`] of its box,
//! with text in it), one band plot per output and the sensitivity plots, and every number of the
//! page's tables equal to the summary JSON's, to the last bit (the shown text to its seven
//! digits). The untrusted study's page shows its warnings first and marks the untrusted outputs.
//!
//! Needs Chromium (Debian's `chromium`; installed by the test only on CI or with
//! `RIBBON_TEST_INSTALL=1`, as root, otherwise it fails naming the command), Node.js with npm
//! (Debian's `nodejs npm`, the same way), and playwright-core, which the test installs with npm
//! under the target directory (`target/report-page-node`, ~10 MB; no system change). It never
//! skips.

mod common;

use common::{
    ensure_system_programs, fresh_test_scratch_dir, manifest, ribbon_output, run_checked,
    target_dir,
};
use serde_json::Value;
use std::fs::{self, File};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The playwright-core the page check runs on (the same as scripts/viewers/foxglove.sh).
const PLAYWRIGHT_CORE: &str = "playwright-core@1.64.1";
/// Smallest share of a picture's pixels that must be painted (not white) for it to count as drawn:
/// a band or sensitivity plot paints its axes, labels, band and lines (measured: 18–52 % on the
/// ur5), an empty or undecodable one nothing.
const MIN_PAINTED_FRACTION: f64 = 0.05;
/// Relative difference allowed between a shown number (seven significant digits, `{:.6e}`) and
/// the exact value: half a unit in the seventh digit is 5e-7 of the leading digit.
const SHOWN_DIGITS_RELATIVE: f64 = 5e-7;

/// The Chromium the page is opened in (`CHROMIUM`, else Debian's `chromium` on `PATH`).
fn chromium() -> PathBuf {
    if let Some(path) = std::env::var_os("CHROMIUM") {
        return PathBuf::from(path);
    }
    ensure_system_programs("report_page", &["chromium"], &["chromium"]);
    let out = run_checked(
        Path::new("sh"),
        &["-c".to_string(), "command -v chromium".to_string()],
        "locating chromium",
    );
    PathBuf::from(String::from_utf8_lossy(&out.stdout).trim())
}

/// `node_modules` holding playwright-core, installed once per target directory under a lock.
fn node_modules() -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        ensure_system_programs("report_page", &["node", "npm"], &["nodejs", "npm"]);
        let prefix = target_dir().join("report-page-node");
        fs::create_dir_all(&prefix).expect("create target/report-page-node");
        let lock = File::create(prefix.join(".lock")).expect("the npm lock file");
        lock.lock().expect("lock target/report-page-node");
        let modules = prefix.join("node_modules");
        let stamp = prefix.join("installed.stamp");
        if fs::read_to_string(&stamp).ok().as_deref() != Some(PLAYWRIGHT_CORE) {
            eprintln!(
                "report_page: npm install {PLAYWRIGHT_CORE} into {}",
                prefix.display()
            );
            run_checked(
                Path::new("npm"),
                &common::args([
                    "install",
                    "--silent",
                    "--no-audit",
                    "--no-fund",
                    "--prefix",
                    prefix.to_str().expect("UTF-8 path"),
                    PLAYWRIGHT_CORE,
                ]),
                "report_page: installing playwright-core",
            );
            fs::write(&stamp, PLAYWRIGHT_CORE).expect("write the npm stamp");
        }
        modules
    })
    .clone()
}

/// What the browser made of `page` (the JSON of report_page.mjs); its screenshot at `screenshot`.
fn open_in_browser(page: &Path, scratch: &Path, screenshot: &Path) -> Value {
    let chromium = chromium();
    let modules = node_modules();
    let profile = scratch.join("chromium-profile");
    let _ = fs::remove_dir_all(&profile);
    fs::create_dir_all(&profile).expect("an empty Chromium profile directory");
    let script = manifest("tests/reference/report_page.mjs");
    let output = std::process::Command::new("node")
        .arg(&script)
        .arg(page)
        .arg(&profile)
        .arg(screenshot)
        .env("NODE_PATH", &modules)
        .env("CHROMIUM", &chromium)
        .output()
        .expect("node runs");
    assert!(
        output.status.success(),
        "node {} {} failed ({:?}):\n{}\n{}",
        script.display(),
        page.display(),
        output.status.code(),
        String::from_utf8_lossy(&output.stderr),
        String::from_utf8_lossy(&output.stdout)
    );
    serde_json::from_slice(&output.stdout).unwrap_or_else(|e| {
        panic!(
            "report_page.mjs printed no JSON ({e}):\n{}",
            String::from_utf8_lossy(&output.stdout)
        )
    })
}

/// A study with `--summary`, `--report` (and the `extra` flags) into `dir`; the exit code must be
/// `expected_exit`. Returns the summary JSON and the page's path.
fn study(urdf: &Path, extra: &[&str], dir: &Path, expected_exit: i32) -> (Value, PathBuf) {
    let summary = dir.join("summary.json");
    let report = dir.join("report");
    let mut args = vec![
        "analyze",
        urdf.to_str().expect("UTF-8 path"),
        "--summary",
        summary.to_str().expect("UTF-8 path"),
        "--report",
        report.to_str().expect("UTF-8 path"),
    ];
    args.extend_from_slice(extra);
    let out = ribbon_output(&args);
    assert_eq!(
        out.status.code(),
        Some(expected_exit),
        "ribbon {args:?}:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json = serde_json::from_str(&fs::read_to_string(&summary).expect("the summary"))
        .expect("the summary is JSON");
    (json, report.join("index.html"))
}

/// A browser-rendered page's verdict: nothing logged, nothing fetched, every picture drawn.
fn assert_renders_offline(seen: &Value) {
    let problems: Vec<&Value> = seen["console"]
        .as_array()
        .expect("console")
        .iter()
        .filter(|m| m["type"] == "error" || m["type"] == "warning")
        .collect();
    assert!(problems.is_empty(), "console: {problems:?}");
    for key in ["page_errors", "failed_requests", "external_requests"] {
        assert_eq!(
            seen[key].as_array().map(Vec::len),
            Some(0),
            "{key}: {}",
            seen[key]
        );
    }
    for picture in seen["pictures"].as_array().expect("pictures") {
        assert!(picture["error"].is_null(), "a picture failed: {picture}");
        let painted = picture["painted_fraction"]
            .as_f64()
            .expect("painted_fraction");
        assert!(
            painted > MIN_PAINTED_FRACTION,
            "a picture is (nearly) blank: {picture}"
        );
        assert!(
            picture["width"].as_f64() > Some(100.0) && picture["height"].as_f64() > Some(50.0),
            "a picture has no size on the page: {picture}"
        );
        assert!(
            picture["texts"].as_u64() > Some(0),
            "a picture has no text: {picture}"
        );
    }
}

/// The pictures of `kind` (`band`, `sensitivity`) the page has, by output.
fn pictures_of(seen: &Value, kind: &str) -> Vec<String> {
    seen["pictures"]
        .as_array()
        .expect("pictures")
        .iter()
        .filter(|p| p["kind"] == kind)
        .map(|p| p["output"].as_str().unwrap_or_default().to_string())
        .collect()
}

/// A cell's exact value, which must be the f64 `expected` bit for bit, and its shown text, which
/// must round to it.
fn assert_cell(cells: &Value, key: &str, expected: f64, what: &str) {
    let cell = &cells[key];
    let value: f64 = cell["value"]
        .as_str()
        .unwrap_or_else(|| panic!("{what}: no exact value for {key}: {cells}"))
        .parse()
        .unwrap_or_else(|e| panic!("{what}: {key} is not a number ({e}): {cell}"));
    assert_eq!(
        value.to_bits(),
        expected.to_bits(),
        "{what}: the page's {key} is {value:e}, the summary's {expected:e}"
    );
    let shown: f64 = cell["text"]
        .as_str()
        .and_then(|t| t.trim().trim_end_matches(" s").parse().ok())
        .unwrap_or_else(|| panic!("{what}: {key}'s text is not a number: {cell}"));
    assert!(
        (shown - expected).abs() <= SHOWN_DIGITS_RELATIVE * expected.abs().max(f64::MIN_POSITIVE)
            || (key == "wall_seconds" && (shown - expected).abs() <= 5e-4),
        "{what}: {key} is shown as {shown}, the summary has {expected}"
    );
}

/// Every number of the page's tables against the summary JSON.
fn assert_numbers_are_the_summarys(seen: &Value, summary: &Value) {
    let study = &seen["study"];
    assert_eq!(study["method"]["text"], summary["method"], "{study}");
    assert_eq!(study["robot"]["text"], summary["robot"], "{study}");
    assert_eq!(
        study["bound_kind"]["text"], summary["bound_kind"],
        "{study}"
    );
    assert_cell(
        study,
        "samples",
        summary["samples"].as_f64().unwrap(),
        "study",
    );
    assert_cell(
        study,
        "wall_seconds",
        summary["wall_seconds"].as_f64().unwrap(),
        "study",
    );
    let check = &summary["stats"]["check"];
    let trusted = match check["trusted"].as_bool() {
        Some(t) => t.to_string(),
        None => "none".to_string(),
    };
    assert_eq!(study["trusted"]["value"], trusted.as_str(), "{study}");

    let outputs = summary["outputs"].as_array().expect("outputs");
    let rows = seen["envelope_rows"].as_array().expect("envelope rows");
    assert_eq!(rows.len(), outputs.len(), "one row per output");
    for (row, output) in rows.iter().zip(outputs) {
        let name = output["name"].as_str().unwrap();
        assert_eq!(row["output"], name);
        let series = |key: &str| -> Vec<f64> {
            output[key]
                .as_array()
                .unwrap_or_else(|| panic!("{name}: no {key}"))
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        };
        let (time, lower, nominal, upper) = (
            series("time"),
            series("lower"),
            series("nominal"),
            series("upper"),
        );
        // The widest record, the first of equals (the stdout table's choice).
        let mut k = 0;
        for j in 0..time.len() {
            if upper[j] - lower[j] > upper[k] - lower[k] {
                k = j;
            }
        }
        let cells = &row["cells"];
        assert_cell(cells, "max_width", upper[k] - lower[k], name);
        assert_cell(cells, "time", time[k], name);
        assert_cell(cells, "lower", lower[k], name);
        assert_cell(cells, "nominal", nominal[k], name);
        assert_cell(cells, "upper", upper[k], name);
        if output["error_estimate"].is_array() {
            assert_cell(cells, "error_estimate", series("error_estimate")[k], name);
        }
        if let Some(misfits) = check["outputs"].as_array() {
            let misfit = misfits.iter().find(|m| m["name"] == name).unwrap();
            assert_cell(
                cells,
                "relative_misfit",
                misfit["relative_misfit"].as_f64().unwrap(),
                name,
            );
            let untrusted = check["untrusted_outputs"]
                .as_array()
                .unwrap()
                .iter()
                .any(|n| n == name);
            assert_eq!(row["untrusted"].as_bool(), Some(untrusted), "{name}: {row}");
        }
    }
    let parameters = summary["parameters"].as_array().expect("parameters");
    let rows = seen["parameter_rows"].as_array().expect("parameter rows");
    assert_eq!(rows.len(), parameters.len(), "one row per parameter");
    for (row, p) in rows.iter().zip(parameters) {
        let name = p["name"].as_str().unwrap();
        assert_eq!(row["parameter"], name);
        for key in ["lower", "nominal", "upper"] {
            assert_cell(&row["cells"], key, p[key].as_f64().unwrap(), name);
        }
    }
}

#[test]
fn the_ur5_page_renders_offline_and_its_numbers_are_the_summarys() {
    let dir = fresh_test_scratch_dir("report_page", "ur5");
    let log = dir.join("ur5.mcap");
    let (summary, page) = study(
        &manifest("robots/ur5/ur5.urdf"),
        &["--out", log.to_str().unwrap()],
        &dir,
        0,
    );
    let screenshot = dir.join("index.png");
    let seen = open_in_browser(&page, &dir, &screenshot);
    assert_renders_offline(&seen);
    let names: Vec<String> = summary["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["name"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(
        pictures_of(&seen, "band"),
        names,
        "one band plot per output, in order"
    );
    let sensitivity = pictures_of(&seen, "sensitivity");
    assert!(
        summary["sobol_indices"].is_object() && !sensitivity.is_empty(),
        "the ur5's surrogate study has Sobol' indices, and the page plots them: {sensitivity:?}"
    );
    assert_eq!(
        seen["pictures"].as_array().unwrap().len(),
        names.len() + sensitivity.len(),
        "no other pictures"
    );
    assert_numbers_are_the_summarys(&seen, &summary);
    assert_eq!(seen["warnings"].as_array().map(Vec::len), Some(0));
    // The page names the log and its layout, which --report writes beside it with --out.
    let text = fs::read_to_string(&page).unwrap();
    assert!(text.contains(log.to_str().unwrap()) && text.contains("foxglove-layout.json"));
    assert!(page.with_file_name("foxglove-layout.json").is_file());
    assert!(
        fs::metadata(&screenshot).unwrap().len() > 10_000,
        "a screenshot"
    );
    eprintln!("screenshot: {}", screenshot.display());
}

#[test]
fn an_untrusted_studys_page_shows_its_warnings_first() {
    let dir = fresh_test_scratch_dir("report_page", "untrusted");
    // The double pendulum with its second bar's mass over nine decades and no elements: the
    // check does not trust the surrogate (tests/analysis.rs, the same study).
    let urdf = dir.join("dp.urdf");
    fs::copy(
        manifest("robots/double_pendulum/double_pendulum.urdf"),
        &urdf,
    )
    .unwrap();
    fs::write(
        dir.join("dp.uncertainty.toml"),
        "[parameters]\n\"link.bar2.mass\" = [1e-9, 1.0]\n[scene]\nduration = 2.0\n\
         gravity = [0.0, -9.81, 0.0]\n[outputs]\njoints = \"all\"\nrate = 100\n",
    )
    .unwrap();
    let (summary, page) = study(
        &urdf,
        &["--elements", "off"],
        &dir,
        i32::from(ribbon::UNTRUSTED_EXIT_CODE),
    );
    let seen = open_in_browser(&page, &dir, &dir.join("index.png"));
    assert_renders_offline(&seen);
    assert_eq!(seen["first_section"], "warnings", "the warnings come first");
    let warnings = seen["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().any(|w| w
            .as_str()
            .unwrap()
            .contains("the surrogate cannot be trusted")),
        "{warnings:?}"
    );
    assert_eq!(summary["stats"]["check"]["trusted"], false);
    assert_numbers_are_the_summarys(&seen, &summary);
    assert!(
        seen["envelope_rows"]
            .as_array()
            .unwrap()
            .iter()
            .any(|r| r["untrusted"] == true),
        "an untrusted output is marked"
    );
    // Each untrusted output's band plot: captioned NOT TRUSTED with its misfit, its true runs'
    // range drawn (the SVG's legend names it; tests/untrusted_outputs.rs checks where it is drawn).
    let check = &summary["stats"]["check"];
    let untrusted: Vec<&str> = check["untrusted_outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    let bands: Vec<&Value> = seen["pictures"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["kind"] == "band")
        .collect();
    assert_eq!(bands.len(), summary["outputs"].as_array().unwrap().len());
    let text = fs::read_to_string(&page).unwrap();
    for band in bands {
        let output = band["output"].as_str().unwrap();
        let caption = band["caption"].as_str().unwrap();
        if untrusted.contains(&output) {
            let misfit = check["outputs"]
                .as_array()
                .unwrap()
                .iter()
                .find(|o| o["name"] == output)
                .unwrap()["relative_misfit"]
                .as_f64()
                .unwrap();
            assert_eq!(band["untrusted"], true, "{band}");
            assert!(
                caption.starts_with(&format!(
                    "⚠ {output} [rad] — NOT TRUSTED (misfit {:.1} %)",
                    100.0 * misfit
                )),
                "{caption}"
            );
        } else {
            assert_eq!(band["untrusted"], false, "{band}");
            assert!(!caption.contains("NOT TRUSTED"), "{caption}");
        }
    }
    assert!(!untrusted.is_empty());
    assert!(
        text.contains("true runs&apos; range ("),
        "no band plot names the true runs' range"
    );
    // Without --out the page says how to get a log, and no layout is written.
    assert!(text.contains("This study wrote no MCAP log"), "{text}");
    assert!(!page.with_file_name("foxglove-layout.json").exists());
}
