//! The check that a plan file is the plan this ribbon makes from the same inputs and options
//! (`run` and `merge`, docs/distributed.md §2): the same method, design, box, outputs, record
//! schedule and sample points, bit for bit — records of another design are never merged.
//!
//! Does not: read the plan file or check its inputs' hashes (`distributed::PlanFile`).

use crate::analysis::{RecordSchedule, Study, StudyPlan};
use crate::distributed::{PlanFile, ShardError};
use crate::Error;
use std::path::Path;

/// Refuses a plan that this ribbon, with these inputs, would not make: the same method, design,
/// box, outputs, record schedule and sample points, bit for bit (a different build or edited
/// inputs would merge records of another design).
pub fn check_plan_matches(
    plan: &PlanFile,
    plan_path: &Path,
    study: &Study,
    study_plan: &StudyPlan,
) -> Result<(), Error> {
    let body = &plan.body;
    let mismatch = |what: &str| {
        Error::from(ShardError::Plan {
            path: plan_path.to_path_buf(),
            message: format!(
                "its {what} differs from what this ribbon plans from the same inputs; make the plan again with this ribbon (`ribbon plan`)"
            ),
        })
    };
    let schedule = RecordSchedule::of(study.scene);
    let names: Vec<&str> = study
        .scene
        .outputs
        .iter()
        .map(|o| o.name.as_str())
        .collect();
    let parameters: Vec<&str> = study
        .space
        .dimensions()
        .iter()
        .map(|d| d.name.as_str())
        .collect();
    if body.method != study_plan.method.name() || body.design != study_plan.design_name {
        return Err(mismatch("method or design"));
    }
    if body.outputs != names || body.parameters != parameters || body.nq != study.model.nq {
        return Err(mismatch("outputs or parameters"));
    }
    if (
        body.n_steps,
        body.record_every,
        body.step_s.to_bits(),
        body.records,
    ) != (
        schedule.n_steps,
        schedule.record_every,
        schedule.step_bits,
        schedule.len(),
    ) {
        return Err(mismatch("record schedule"));
    }
    // A staged design's first stage is checked when the study reaches it (its points are chosen
    // by the study's first phase, not by the plan).
    let points = study.design_points(study_plan);
    if points.is_none() != body.staged.is_some() {
        return Err(mismatch("design (fixed or staged)"));
    }
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    if points.is_some_and(|points| bits(&points) != bits(&plan.points()))
        || bits(&study.space.nominal_xi()) != bits(&body.nominal_xi)
        || body.check_runs != study_plan.check_runs
    {
        return Err(mismatch("sample list"));
    }
    Ok(())
}
