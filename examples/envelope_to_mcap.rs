//! Runs a small study through the library API and logs its envelopes to MCAP for Foxglove and rerun:
//! the double pendulum with both bar lengths ±1 % (its shipped sidecar), 0.5 s, Legendre scan.
//!
//! `cargo run --release --example envelope_to_mcap -- [OUT.mcap]` (default `target/envelope_example.mcap`)

use ribbon::analysis::{ForeignError, Method, Study, StudyOptions};
use ribbon::dynamics::Data;
use ribbon::output::mcap::McapMetadata;
use ribbon::output::EnvelopeLog;
use ribbon::scene::SceneOverrides;
use ribbon::setup::{print_message, Setup, SetupRequest};
use ribbon::uq::Truncation;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

fn main() -> ExitCode {
    let out = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("target/envelope_example.mcap"));
    match run(&out) {
        Ok(records) => {
            println!(
                "wrote {records} record times of envelopes to {}",
                out.display()
            );
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::from(error.exit_code())
        }
    }
}

fn run(out: &Path) -> Result<usize, ribbon::Error> {
    let urdf = Path::new("robots/double_pendulum/double_pendulum.urdf");
    let sidecar_path = Path::new("robots/double_pendulum/double_pendulum.uncertainty.toml");
    let request = SetupRequest {
        urdf,
        uncertainty: Some(sidecar_path),
        floating: false,
        overrides: SceneOverrides {
            duration_s: Some(0.5),
            ..SceneOverrides::default()
        },
    };
    let Setup {
        model,
        environment,
        scene,
        space,
        ..
    } = Setup::load(&request, &mut print_message)?;
    let options = StudyOptions {
        method: Method::LegendreScan,
        order: 4,
        truncation: Truncation::Tensor,
        grid: 21,
        scan_grid: None,
        samples: 0,
        seed: 0,
        threads: 0,
        keep_going: false,
        check_runs: None,
        elements: ribbon::analysis::ElementsOptions::default(),
        design: ribbon::analysis::DesignKind::Tensor,
        max_runs: ribbon::analysis::DEFAULT_MAX_RUNS,
    };
    let study = Study {
        model: model.clone(),
        environment,
        scene: &scene,
        space: &space,
        options,
    };
    let runs = study.plan()?.max_runs();
    let metadata = McapMetadata {
        robot: model.name().to_string(),
        method: "legendre-scan".to_string(),
        order: Some(4),
        runs,
        parameters_json: "[]".to_string(),
    };
    let mut log = EnvelopeLog::create(
        out,
        urdf,
        Some(sidecar_path),
        metadata,
        &scene.outputs,
        true,
    )?;
    let mut data = Data::new(&model);
    let report = study.run(&AtomicBool::new(false), &mut |_| {}, &mut |block| {
        log.write_block(block, &model, &mut data)
            .map_err(ForeignError::new)
    })?;
    log.finish(false)?;
    Ok(report.envelope.times.len())
}
