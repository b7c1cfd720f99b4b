//! The a-posteriori check's resolution floor (docs/method.md §7): an output whose misfit is a large
//! share of a tiny envelope, but smaller than what the integrator resolves, is numerical noise and
//! must not make the study "not trusted"; a misfit above the floor still must.
//!
//! The vehicle drives straight, so its frames' y coordinates stay at rounding level (widths
//! ~4e-17 m): without the floor the check reported them "not trusted" with misfits of 53–58 % of
//! those widths. `tests/analysis.rs` keeps the other side: a double-pendulum box across nine
//! decades of mass is still reported untrusted.

mod common;

use serde_json::Value;

#[test]
fn rounding_level_envelopes_are_below_resolution_and_real_misfits_are_not() {
    let dir = common::target_dir().join("check-resolution-test");
    std::fs::create_dir_all(&dir).expect("mkdir");
    let summary_path = dir.join("vehicle.json");
    let out = std::process::Command::new(common::ribbon_bin())
        .current_dir(common::manifest_dir())
        .args([
            "analyze",
            "robots/vehicle/vehicle.urdf",
            "--duration",
            "0.2",
            "--order",
            "2",
            "--summary",
            summary_path.to_str().expect("UTF-8"),
        ])
        .output()
        .expect("run ribbon");
    let stderr = String::from_utf8_lossy(&out.stderr);
    // The shortened study (order 2) is not trusted on a suspension joint (5.1 % misfit): exit 4,
    // results written. The exit status must say what the summary says.
    let untrusted_exit = out.status.code() == Some(i32::from(ribbon::UNTRUSTED_EXIT_CODE));
    assert!(out.status.success() || untrusted_exit, "{stderr}");
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(&summary_path).expect("summary"))
            .expect("JSON");
    let check = &summary["stats"]["check"];
    let names = |key: &str| -> Vec<String> {
        check[key]
            .as_array()
            .unwrap_or_else(|| panic!("stats.check.{key}"))
            .iter()
            .map(|v| v.as_str().expect("name").to_string())
            .collect()
    };
    let below = names("below_resolution_outputs");
    let untrusted = names("untrusted_outputs");
    for frame in ["chassis", "nose", "tail"] {
        let name = format!("frame.{frame}.y");
        assert!(
            below.contains(&name),
            "{name} not below resolution: {check}"
        );
        assert!(
            !untrusted.contains(&name),
            "{name} reported untrusted: {check}"
        );
    }
    assert!(
        stderr.contains("less than the integrator's resolution"),
        "no note on stderr:\n{stderr}"
    );
    let factor = check["trust_resolution_factor"].as_f64().expect("factor");
    let threshold = check["trust_relative_misfit"].as_f64().expect("threshold");
    // Every output over the relative threshold is in exactly one list, by its misfit against its
    // resolution; outputs without a resolution (forces, velocities) are never excused.
    for output in check["outputs"].as_array().expect("outputs") {
        let name = output["name"].as_str().expect("name").to_string();
        let relative = output["relative_misfit"].as_f64().expect("relative");
        let misfit = output["max_misfit"].as_f64().expect("misfit");
        let resolution = output["resolution"].as_f64();
        if name.starts_with("contact.") || name.starts_with("v.") {
            assert!(resolution.is_none(), "{name}: {output}");
        }
        if relative > threshold {
            let excused = resolution.is_some_and(|r| misfit <= factor * r);
            assert_eq!(below.contains(&name), excused, "{name}: {output}");
            assert_eq!(untrusted.contains(&name), !excused, "{name}: {output}");
        } else {
            assert!(
                !below.contains(&name) && !untrusted.contains(&name),
                "{name}"
            );
        }
    }
    assert_eq!(check["trusted"], untrusted.is_empty());
    assert_eq!(untrusted_exit, !untrusted.is_empty(), "{stderr}");
}
