//! The viewer files against a fresh log (docs/mcap.md §4–§5): the rerun blueprint written by
//! `scripts/viewers/rerun_blueprint.py` plots only entities that exist and are non-empty in the
//! converted recording, titles carry units, the timeline counts seconds from 0
//! (`tests/reference/check_blueprint.py`). The Foxglove layout attachment is checked by
//! `tests/mcap_cli.rs` through `tests/reference/check_mcap.py`. No browser and no GPU here: the
//! screenshot check is `scripts/viewers/screenshots.sh`.

mod common;

use std::path::PathBuf;
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    let dir = common::target_dir().join("tmp").join("viewers");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn rerun_blueprint_plots_only_live_entities_of_a_fresh_log() {
    let out = scratch("slider_crank.mcap");
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
    let python = common::reference_python();
    let result = Command::new(&python)
        .arg(common::manifest_dir().join("tests/reference/check_blueprint.py"))
        .arg(&out)
        .arg(scratch("blueprint_work"))
        .output()
        .expect("python runs");
    assert!(
        result.status.success(),
        "check_blueprint.py failed:\n{}\n{}",
        String::from_utf8_lossy(&result.stdout),
        String::from_utf8_lossy(&result.stderr)
    );
    println!("{}", String::from_utf8_lossy(&result.stdout));
}
