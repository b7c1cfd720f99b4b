//! `legendre-bernstein` in a study (docs/bernstein.md): on the shipped ur5 box (d = 3, 1 s) its
//! envelope contains the scanned surrogate's at every output and record time (it is an outer
//! bound of the same surrogate) and closes on it, where interval arithmetic stays wide.

mod common;

use ribbon::analysis::{DesignKind, Method, Study, StudyOptions, StudyReport};
use ribbon::uq::Truncation;
use std::sync::atomic::AtomicBool;

/// Largest gap allowed between the Bernstein envelope and the scan's, relative to the output's
/// widest envelope: the bounder stops within 1e-6 of the width of each surrogate's range, and the
/// scan (grid + projected Newton) attains the extremes to about that.
const GAP_TOL: f64 = 1e-5;
/// Containment up to rounding, relative to the width.
const ROUNDING: f64 = 1e-12;

fn run(method: Method) -> StudyReport {
    let setup = common::shipped_setup(
        "robots/ur5/ur5.urdf",
        "robots/ur5/ur5.uncertainty.toml",
        1.0,
    );
    let (model, scene, space) = (setup.model, setup.scene, setup.space);
    let study = Study {
        model,
        environment: scene.environment(),
        scene: &scene,
        space: &space,
        options: StudyOptions {
            method,
            order: 4,
            truncation: Truncation::Tensor,
            design: DesignKind::Tensor,
            max_runs: 10_000,
            grid: 21,
            scan_grid: None,
            samples: 0,
            seed: 0,
            threads: 2,
            keep_going: false,
            check_runs: Some(0),
            elements: ribbon::analysis::ElementsOptions::default(),
        },
    };
    study
        .run(&AtomicBool::new(false), &mut |_| {}, &mut |_| Ok(()))
        .unwrap()
}

#[test]
fn bernstein_envelopes_contain_and_close_on_the_scan() {
    let scan = run(Method::LegendreScan).envelope;
    let bernstein = run(Method::LegendreBernstein).envelope;
    let ia = run(Method::LegendreIa).envelope;
    let (mut worst_gap, mut worst_ia) = (0.0_f64, 0.0_f64);
    for o in 0..scan.outputs.len() {
        let width = (0..scan.times.len())
            .map(|k| scan.upper[o][k] - scan.lower[o][k])
            .fold(0.0, f64::max);
        if width == 0.0 {
            continue;
        }
        for k in 0..scan.times.len() {
            let below = scan.lower[o][k] - bernstein.lower[o][k];
            let above = bernstein.upper[o][k] - scan.upper[o][k];
            assert!(
                below >= -ROUNDING * width && above >= -ROUNDING * width,
                "{} at t = {}: Bernstein [{}, {}] inside the scan [{}, {}]",
                scan.outputs[o].name,
                scan.times[k],
                bernstein.lower[o][k],
                bernstein.upper[o][k],
                scan.lower[o][k],
                scan.upper[o][k]
            );
            worst_gap = worst_gap.max(below.max(above) / width);
            let ia_gap = (scan.lower[o][k] - ia.lower[o][k]).max(ia.upper[o][k] - scan.upper[o][k]);
            worst_ia = worst_ia.max(ia_gap / width);
        }
    }
    println!("largest gap to the scan, relative to the width: Bernstein {worst_gap:.2e}, interval arithmetic {worst_ia:.2e}");
    assert!(worst_gap < GAP_TOL, "Bernstein gap {worst_gap}");
    assert!(
        worst_ia > 100.0 * worst_gap,
        "interval arithmetic is the wider outer bound"
    );
}
