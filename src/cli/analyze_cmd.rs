//! `ribbon analyze ROBOT.urdf [--uncertainty F] [--method M] [--order K] [--design tensor|total]
//! [--grid N] [--scan-grid N] [--samples N] [--seed S] [--threads N] [--keep-going] [--summary F]
//! [--csv F] [--out F.mcap] [--report DIR]`: bound envelopes. A progress line on stderr, a table on stdout.
//! Outputs are checked before anything runs. SIGINT/SIGTERM finish the current block, write what was
//! computed (MCAP marked partial) and exit 1; a second signal exits at once, removing the temporary
//! files. The study itself is [`crate::study_front::run_study`].

use super::AnalyzeArgs;
use crate::study_front::{run_study, StudyFlags, StudyOutputs, StudyRequest};
use crate::Error;

/// Runs `ribbon analyze`.
pub fn run(args: &AnalyzeArgs) -> Result<(), Error> {
    run_study(&args.request(), None)
}

impl AnalyzeArgs {
    /// The study these flags ask for.
    pub fn request(&self) -> StudyRequest {
        StudyRequest {
            scene: self.scene.inputs(),
            flags: StudyFlags {
                method: self.method.clone(),
                order: self.order,
                design: self.design.clone(),
                grid: self.grid,
                scan_grid: self.scan_grid,
                samples: self.samples,
                seed: self.seed,
                threads: self.threads,
                keep_going: self.keep_going,
                max_runs: self.max_runs,
                check_runs: self.check_runs,
                elements: self.elements.clone(),
                max_elements: self.max_elements,
            },
            outputs: StudyOutputs {
                summary: self.summary.clone(),
                csv: self.csv.clone(),
                out: self.out.clone(),
                report: self.report.clone(),
            },
        }
    }
}
