//! The viewer files against a fresh log (docs/mcap.md §4–§5): the rerun blueprint written by
//! `scripts/viewers/rerun_blueprint.py` plots only entities that exist and are non-empty in the
//! converted recording, titles carry units, the timeline counts seconds from 0, an untrusted
//! study's untrusted outputs are titled as such with their true runs' hull plotted beside the
//! envelope (`tests/reference/check_blueprint.py`). The Foxglove layout attachment is checked by
//! `tests/mcap_cli.rs` through `tests/reference/check_mcap.py`. No browser and no GPU here: the
//! screenshot check is `scripts/viewers/screenshots.sh`.

mod common;

use common::scratch_file;

use std::process::Command;

#[test]
fn rerun_blueprint_plots_only_live_entities_of_a_fresh_log() {
    let out = scratch_file("viewers", "slider_crank.mcap");
    let status = Command::new(common::ribbon_bin())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "analyze",
            "robots/slider_crank/slider_crank.urdf",
            "--duration",
            "0.3",
            "--out",
        ])
        .arg(&out)
        .status()
        .expect("ribbon runs");
    assert!(status.success());
    check_blueprint(&out, "blueprint_work");
}

/// An untrusted study (the double pendulum falling from upright, fixture `refine_chaos`, exit 4):
/// its untrusted outputs' views say so and plot the hull of their true runs.
#[test]
fn rerun_blueprint_shows_an_untrusted_outputs_true_runs() {
    let out = scratch_file("viewers", "refine_chaos.mcap");
    let status = Command::new(common::ribbon_bin())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "analyze",
            "robots/double_pendulum/double_pendulum.urdf",
            "--uncertainty",
            "tests/fixtures/refine_chaos/upright.uncertainty.toml",
            "--max-runs",
            "600",
            "--out",
        ])
        .arg(&out)
        .status()
        .expect("ribbon runs");
    assert_eq!(status.code(), Some(4), "the study must be untrusted");
    let report = check_blueprint(&out, "blueprint_untrusted");
    assert!(report.contains(" 2 true-run hulls"), "{report}");
}

/// Runs `tests/reference/check_blueprint.py` on the log `out` (work files in the scratch
/// directory `work`); returns its report line.
fn check_blueprint(out: &std::path::Path, work: &str) -> String {
    let python = common::reference_python();
    let result = Command::new(&python)
        .arg(common::manifest_dir().join("tests/reference/check_blueprint.py"))
        .arg(out)
        .arg(scratch_file("viewers", work))
        .output()
        .expect("python runs");
    assert!(
        result.status.success(),
        "check_blueprint.py failed:\n{}\n{}",
        String::from_utf8_lossy(&result.stdout),
        String::from_utf8_lossy(&result.stderr)
    );
    let report = String::from_utf8_lossy(&result.stdout).into_owned();
    println!("{report}");
    report
}

#[test]
fn analyze_report_holds_a_band_plot_per_output_and_the_logs_layout() {
    let dir = scratch_file("viewers", "report_dp");
    let _ = std::fs::remove_dir_all(&dir);
    let out = scratch_file("viewers", "report_dp.mcap");
    let result = Command::new(common::ribbon_bin())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "analyze",
            "robots/double_pendulum/double_pendulum.urdf",
            "--duration",
            "0.3",
            "--out",
        ])
        .arg(&out)
        .arg("--report")
        .arg(&dir)
        .output()
        .expect("ribbon runs");
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let page = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(
        !page.contains("**Warning:**"),
        "a trusted study has no warning: {page}"
    );
    for (name, unit) in [
        ("q.j1", "rad"),
        ("q.j2", "rad"),
        ("frame.tip.x", "m"),
        ("frame.tip.y", "m"),
        ("frame.tip.z", "m"),
    ] {
        assert!(page.contains(&format!("## {name} [{unit}]")), "{page}");
        assert!(page.contains(&format!("({name}.svg)")), "{page}");
        let svg = std::fs::read_to_string(dir.join(format!("{name}.svg"))).unwrap();
        assert!(svg.starts_with("<svg"), "{name}.svg");
        assert!(
            svg.contains(&format!("{name} [{unit}]")),
            "{name}.svg names its unit"
        );
        assert!(svg.contains("<polygon"), "{name}.svg shades the band");
        assert!(svg.contains("nominal") && svg.contains("inner bound"));
        if name.starts_with("q.") {
            // The a-posteriori check's true runs at the predicted extremes are drawn as dots.
            assert!(
                svg.contains("true runs at predicted extremes") && svg.contains("<circle"),
                "{name}.svg has no check dots"
            );
        }
        let png = std::fs::read(dir.join(format!("{name}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{name}.png");
    }
    // The layout file is the one attached to the log.
    let bytes = std::fs::read(&out).unwrap();
    let attached = mcap::read::LinearReader::new(&bytes)
        .unwrap()
        .filter_map(|record| match record.unwrap() {
            mcap::records::Record::Attachment { header, data, .. }
                if header.name == "foxglove-layout.json" =>
            {
                Some(data.into_owned())
            }
            _ => None,
        })
        .next()
        .expect("the log holds the layout");
    assert_eq!(
        std::fs::read(dir.join("foxglove-layout.json")).unwrap(),
        attached
    );
}

#[test]
fn a_report_file_that_is_another_output_is_refused_before_running() {
    let dir = scratch_file("viewers", "report_clash");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let result = Command::new(common::ribbon_bin())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "analyze",
            "robots/double_pendulum/double_pendulum.urdf",
            "--duration",
            "0.3",
            "--csv",
        ])
        .arg(dir.join("q.j1.png"))
        .arg("--report")
        .arg(&dir)
        .output()
        .expect("ribbon runs");
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("q.j1.png"), "{stderr}");
    assert!(!dir.join("report.md").exists());
}
