//! Sensitivities of every recorded output to every dimension of a study's box, at one point ξ
//! (docs/sensitivities.md):
//!
//! - [`sensitivity_run`]: one trajectory with its forward sensitivities (direct differentiation of
//!   the HHT-I3 step, [`HhtSensitivity`]), the outputs and `∂y/∂ξ_j` at every record time;
//! - [`central_difference_run`]: the checked fallback, `2d + 1` plain runs at `ξ` and
//!   `ξ ± h e_j`, same shape.
//!
//! `(model, scene, space, ξ) ⇒ RobotSystem at ξ with one parameter direction per dimension
//! ⇒ HhtIntegrator + HhtSensitivity steps ⇒ per record: Recorder values and output derivatives`
//!
//! Output derivatives (docs/sensitivities.md §7): joint coordinates, velocities, accelerations and
//! multipliers are rows of the state sensitivities; a frame position is its Jacobian times `S_q`
//! plus, for dimensions that move joint origins or axes, a central difference of its forward
//! kinematics in the model values; a floating base's position is `R S_v`-like (its rotation times
//! the tangent's linear part) and its rotation vector relative to the start moves by
//! `J_r(y)⁻¹ δω − J_r(−y)⁻¹ δω_0`.

use super::lie::so3_right_jacobian_inverse;
use super::run::{hht_settings, initial_violation, record_current_state};
use super::SimulationError;
use super::{Recorder, RobotSystem};
use crate::dynamics::{forward_kinematics, link_origin_jacobian, world_from_link};
use crate::environment::Environment;
use crate::integrate::{
    HhtIntegrator, HhtSensitivity, HhtSettings, HhtStats, Parameters, SensitivityError,
    SensitivityStats,
};
use crate::model::{JointKind, Model};
use crate::scene::{Output, OutputKind, Scene};
use crate::spatial::quaternion::unit_quaternion_from_xyzw;
use crate::spatial::Vec3;
use crate::uncertainty::ParameterSpace;
use nalgebra::{DMatrix, DVector, UnitQuaternion};

/// The orientation of the floating joint whose coordinates start at `q_index` (x y z, then the
/// quaternion x y z w).
fn orientation(q: &[f64], q_index: usize) -> UnitQuaternion<f64> {
    unit_quaternion_from_xyzw(&q[q_index + 3..q_index + 7])
}

/// Step in ξ of [`central_difference_run`] (0.1 % of each dimension's half-width). The truncation
/// error is ~h²/6 ≈ 2e-7 of the third derivative in ξ (outputs are smooth on the scale of the box);
/// with the tight Newton tolerances of [`central_difference_settings`] the Newton noise costs
/// ~1e-15/h ≈ 1e-12 on positions. Accelerations, efforts and constraint forces of scenes with
/// constraint rows are noisier: index-3 integration leaves them a rounding floor of about
/// `u·|q|/(β'h_t²)` (~1e-9 at a 1 ms step), which the difference turns into ~1e-6 absolute.
pub const CENTRAL_DIFFERENCE_STEP_XI: f64 = 1e-3;

/// The 4-point central-difference stencil of the frames' geometric part: `(offset in steps,
/// weight / 12)`.
const FRAME_STENCIL: [(f64, f64); 4] = [(2.0, -1.0), (1.0, 8.0), (-1.0, -8.0), (-2.0, 1.0)];

/// Newton tolerances of the runs of [`central_difference_run`], close to rounding so that the
/// difference of two runs measures the parameter and not where Newton stopped: at the position
/// level 1e-15 rad or m with constraint rows (their rounding floor: `Φ` rounds at ~1e-16, and the
/// scaled rows turn that into a correction of `β'h² Δq̈` ≈ 1e-16), 1e-16 without (1e-10 by
/// default; the floor there is `u · |q̈| · β'h²`, ~1e-21 for an arm, but ~1e-17 with accelerations
/// of 1e5 rad/s² — stiffer scenes than that may pass their own settings to
/// [`central_difference_run_with`]); relative 1e-15 (a floating base's translation of 1 m rounds
/// at 1.1e-16); 1e-10 N or N·m on multipliers.
pub fn central_difference_settings(scene: &Scene) -> HhtSettings {
    HhtSettings {
        reltol: 1e-15,
        abstol_position: if scene.constraints.is_empty() {
            1e-16
        } else {
            1e-15
        },
        abstol_multiplier: 1e-10,
        // Newton converged to rounding at every step: a reused matrix accepts iterates anywhere
        // below the tolerance, which the difference quotient divides by its step.
        reuse_newton_matrix: false,
        // Likewise the first correction accepted by the last step's contraction.
        accept_by_carried_contraction: false,
        // Likewise the predictor's order chosen by the history.
        choose_predictor_order: false,
        // The projection's metric at q_{n+1}: the sensitivities differentiate that projection,
        // and one at the Newton matrix's iterate depends on where the iteration started.
        projection_keeps_newton_mass: false,
        ..hht_settings(scene)
    }
}

/// Why a sensitivity run failed.
#[derive(Debug, thiserror::Error)]
pub enum SensitivityRunError {
    /// ξ does not have one coordinate per dimension of the box.
    #[error("the parameter point has {got} coordinates but the box has {expected} dimensions")]
    PointDimension {
        /// d.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// A coordinate of ξ is NaN or infinite.
    #[error("the parameter point's coordinate {index} ({name}) is {value}; it must be finite")]
    NonFinitePoint {
        /// Dimension index.
        index: usize,
        /// Its name in the sidecar.
        name: String,
        /// The value.
        value: f64,
    },
    /// The central-difference step is not a finite number > 0.
    #[error("the central-difference step in ξ is {step}; it must be finite and > 0 (default {CENTRAL_DIFFERENCE_STEP_XI})")]
    InvalidStep {
        /// The step given.
        step: f64,
    },
    /// A run (nominal, or one of the central difference's) failed.
    #[error("{run}: {source}")]
    Simulation {
        /// Which run: "the sensitivity run", "the run at ξ + h e_3", …
        run: String,
        /// Why.
        source: SimulationError,
    },
    /// The sensitivity bookkeeping was misused (a bug, not bad input).
    #[error(transparent)]
    Sensitivity(SensitivityError),
    /// An output whose derivative ribbon has no rule for.
    #[error(
        "output '{name}' has no sensitivity rule: a position output must be a 1-dof joint's \
         coordinate (a floating base is recorded through its q.BASE.x|y|z|rx|ry|rz outputs)"
    )]
    UnsupportedOutput {
        /// The output's name.
        name: String,
    },
}

/// Counters of a sensitivity or central-difference run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SensitivityRunStats {
    /// Model runs made (1 for [`sensitivity_run`], `2d + 1` for [`central_difference_run`]).
    pub runs: usize,
    /// Integrator statistics of the run at ξ itself.
    pub nominal: HhtStats,
    /// Newton iterations over all runs.
    pub newton_iterations: u64,
    /// The forward sensitivities' counters ([`sensitivity_run`] only).
    pub sensitivity: Option<SensitivityStats>,
}

/// Every output and its derivatives with respect to every dimension of ξ, at every record time of
/// one trajectory at one point ξ.
#[derive(Clone, Debug)]
pub struct SensitivityRun {
    /// Record times, s (`n_records`).
    pub times: Vec<f64>,
    /// The outputs, in column order (`n_outputs`).
    pub outputs: Vec<Output>,
    /// The box's dimension names, in ξ order (`d`).
    pub dimensions: Vec<String>,
    /// The point ξ (dim d).
    pub xi: Vec<f64>,
    /// `values[r · n_outputs + o]`: output `o` at `times[r]`, the numbers [`Recorder`] produces.
    pub values: Vec<f64>,
    /// `jacobian[(r · n_outputs + o) · d + j]`: `∂y_o/∂ξ_j` at `times[r]`, in the output's unit per
    /// unit ξ (ξ_j = ±1 are the box's faces, so this is the change over one half-width to first
    /// order; divide by the dimension's radius for the derivative in its physical unit).
    pub jacobian: Vec<f64>,
    /// What it cost.
    pub stats: SensitivityRunStats,
}

impl SensitivityRun {
    /// Number of record times.
    pub fn n_records(&self) -> usize {
        self.times.len()
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.outputs.len()
    }

    /// Number of dimensions d.
    pub fn n_dimensions(&self) -> usize {
        self.dimensions.len()
    }

    /// Output `output` at record `record`.
    pub fn value(&self, record: usize, output: usize) -> f64 {
        self.values[record * self.outputs.len() + output]
    }

    /// `∂y_output/∂ξ_dimension` at record `record`.
    pub fn derivative(&self, record: usize, output: usize, dimension: usize) -> f64 {
        let d = self.dimensions.len();
        self.jacobian[(record * self.outputs.len() + output) * d + dimension]
    }
}

fn check_point(space: &ParameterSpace, xi: &[f64]) -> Result<(), SensitivityRunError> {
    if xi.len() != space.len() {
        return Err(SensitivityRunError::PointDimension {
            expected: space.len(),
            got: xi.len(),
        });
    }
    if let Some(index) = xi.iter().position(|x| !x.is_finite()) {
        return Err(SensitivityRunError::NonFinitePoint {
            index,
            name: space.dimensions()[index].name.clone(),
            value: xi[index],
        });
    }
    Ok(())
}

/// The robot system of `scene` with the point `xi` written into its model (the study engine's
/// order: effects assembled, then the point applied).
fn system_at(
    model: Model,
    environment: Environment,
    scene: &Scene,
    space: &ParameterSpace,
    xi: &[f64],
) -> RobotSystem {
    let mut system = RobotSystem::new(model, environment, scene);
    if !space.is_empty() {
        space.apply(&mut system.model, &mut system.environment, xi);
    }
    system
}

/// [`sensitivity_run_with`] at the scene's integrator settings.
pub fn sensitivity_run(
    model: Model,
    environment: Environment,
    scene: &Scene,
    space: &ParameterSpace,
    xi: &[f64],
) -> Result<SensitivityRun, SensitivityRunError> {
    sensitivity_run_with(model, environment, scene, space, xi, hht_settings(scene))
}

/// One trajectory of `scene` at the point `xi` of `space` (dim d) with the derivatives of every
/// output with respect to every ξ_j, by direct differentiation of each HHT-I3 step
/// (docs/sensitivities.md). `model` and `environment` are prepared as for [`super::simulate`] (the
/// scene's environment); `settings` are the integrator's (the scene's: [`hht_settings`]), with
/// [`HhtSettings::projection_keeps_newton_mass`] off: the derivative of the reported velocity is
/// that of the projection with `M(q_{n+1})` (the values are a plain run's with that setting off).
///
/// Cost: about the plain run plus, per step, the analytic Jacobians of RNEA (about two RNEA
/// passes), one LU of `nv + m` and `d` solves, one regressor column per inertial target and two
/// residual evaluations (four with constraint rows) per dimension that moves geometry; measured on
/// the ur5 (benches/sensitivities.rs): 6.7 plain runs at d = 10, 22.6 at d = 60
/// (docs/sensitivities.md §9).
///
/// Errors: a point of the wrong dimension or not finite; the run's own failures (as
/// [`super::simulate`] reports them).
pub fn sensitivity_run_with(
    model: Model,
    environment: Environment,
    scene: &Scene,
    space: &ParameterSpace,
    xi: &[f64],
    settings: HhtSettings,
) -> Result<SensitivityRun, SensitivityRunError> {
    check_point(space, xi)?;
    let settings = HhtSettings {
        projection_keeps_newton_mass: false,
        ..settings
    };
    let d = space.len();
    let mut system = system_at(model, environment, scene, space, xi);
    let mut list = Vec::new();
    let directions: Vec<_> = (0..d)
        .map(|j| {
            space.target_derivatives(xi, j, &mut list);
            list.clone()
        })
        .collect();
    system.set_parameter_directions(&directions);
    let mut derivatives = OutputDerivatives::new(&system, &scene.outputs, d)?;
    let violation = initial_violation(&mut system, scene);
    let constraints = system.constraints.clone();
    let failed = |e: SensitivityError| match e {
        SensitivityError::Integrate(source) => SensitivityRunError::Simulation {
            run: "the sensitivity run".to_string(),
            source: SimulationError::from_integrate(source, &constraints, violation),
        },
        other => SensitivityRunError::Sensitivity(other),
    };

    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let mut integrator =
        HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).map_err(|e| failed(e.into()))?;
    let mut sensitivity =
        HhtSensitivity::new(&mut system, &integrator, &q0, &v0).map_err(failed)?;
    let recorder = Recorder::new(&scene.outputs);
    let start_q = integrator.state().q.clone();
    let initial = Recorder::initial_orientations(&system.model, start_q.as_slice());

    let n_outputs = scene.outputs.len();
    let n_records = scene.n_steps / scene.record_every + 2;
    let mut times = Vec::with_capacity(n_records);
    let mut values = Vec::with_capacity(n_records * n_outputs);
    let mut jacobian = Vec::with_capacity(n_records * n_outputs * d);
    let mut row = vec![0.0; n_outputs];
    let mut row_derivatives = vec![0.0; n_outputs * d];
    for k in 0..=scene.n_steps {
        if k > 0 {
            sensitivity
                .step(&mut system, &mut integrator)
                .map_err(failed)?;
        }
        if !scene.records_step(k) {
            continue;
        }
        times.push(record_current_state(
            &recorder,
            &mut system,
            &integrator,
            &initial,
            &mut row,
        ));
        values.extend_from_slice(&row);
        derivatives.velocity.copy_from(
            sensitivity
                .reported_velocity(&mut system, &integrator)
                .map_err(failed)?,
        );
        derivatives
            .record(
                &mut system,
                &integrator,
                &sensitivity,
                &start_q,
                &mut row_derivatives,
            )
            .map_err(|e| failed(e.into()))?;
        jacobian.extend_from_slice(&row_derivatives);
    }
    Ok(SensitivityRun {
        times,
        outputs: scene.outputs.clone(),
        dimensions: space.dimensions().iter().map(|x| x.name.clone()).collect(),
        xi: xi.to_vec(),
        values,
        jacobian,
        stats: SensitivityRunStats {
            runs: 1,
            nominal: *integrator.stats(),
            newton_iterations: integrator.stats().newton_iterations,
            sensitivity: Some(*sensitivity.stats()),
        },
    })
}

/// How one output's derivatives are formed (docs/sensitivities.md §7).
#[derive(Clone, Copy, Debug)]
enum Rule {
    /// Row `v_index` of `S_q` (a 1-dof joint's coordinate).
    Coordinate(usize),
    /// Row of the reported velocity's sensitivity.
    Velocity(usize),
    /// Row of `S_q̈`.
    Acceleration(usize),
    /// `sign ·` row of `S_λ`.
    Multiplier { row: usize, sign: f64 },
    /// A link origin's world coordinate `axis`.
    Frame { link: usize, axis: usize },
    /// A floating base's position coordinate `axis` (world frame): `R δv`.
    BasePosition { joint: usize, axis: usize },
    /// A floating base's rotation vector relative to its start, coordinate `axis`:
    /// `J_r(y)⁻¹ δω − J_r(−y)⁻¹ δω_0`.
    BaseRotation { joint: usize, axis: usize },
}

/// The output-derivative rules of a scene and their work buffers.
struct OutputDerivatives {
    rules: Vec<Rule>,
    d: usize,
    /// The reported velocity's sensitivity at the current record, nv × d.
    velocity: DMatrix<f64>,
    /// A link origin's Jacobian, 3 × nv.
    link_jacobian: DMatrix<f64>,
}

impl OutputDerivatives {
    /// The rules of `outputs`. Errors: an output with no rule (a `Position` that is not a 1-dof
    /// joint's coordinate: scenes record a floating base through its pose outputs instead).
    fn new(
        system: &RobotSystem,
        outputs: &[Output],
        d: usize,
    ) -> Result<Self, SensitivityRunError> {
        let model = &system.model;
        let rules = outputs
            .iter()
            .map(|o| match o.kind {
                OutputKind::Position { q_index } => model
                    .joints
                    .iter()
                    .find(|j| j.q_index == q_index && j.kind != JointKind::Floating)
                    .map(|j| Rule::Coordinate(j.v_index))
                    .ok_or_else(|| SensitivityRunError::UnsupportedOutput {
                        name: o.name.clone(),
                    }),
                OutputKind::Velocity { v_index } => Ok(Rule::Velocity(v_index)),
                OutputKind::Acceleration { v_index } => Ok(Rule::Acceleration(v_index)),
                OutputKind::Multiplier { row, sign } => Ok(Rule::Multiplier { row, sign }),
                OutputKind::FramePosition { link, axis } => Ok(Rule::Frame { link, axis }),
                OutputKind::BasePosition { joint, axis } => Ok(Rule::BasePosition { joint, axis }),
                OutputKind::BaseRotation { joint, axis } => Ok(Rule::BaseRotation { joint, axis }),
                OutputKind::ContactNormalForce { .. } => {
                    Err(SensitivityRunError::UnsupportedOutput {
                        name: o.name.clone(),
                    })
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            rules,
            d,
            velocity: DMatrix::zeros(model.nv, d),
            link_jacobian: DMatrix::zeros(3, model.nv),
        })
    }

    /// Writes `∂y_o/∂ξ_j` into `out[o · d + j]` at the integrator's state (`self.velocity` must hold
    /// the reported velocity's sensitivity).
    fn record(
        &mut self,
        system: &mut RobotSystem,
        integrator: &HhtIntegrator,
        sensitivity: &HhtSensitivity,
        start_q: &DVector<f64>,
        out: &mut [f64],
    ) -> Result<(), crate::integrate::IntegrateError> {
        let d = self.d;
        let state = integrator.state();
        let (s_q, s_qdd, s_lambda) = (
            sensitivity.position(),
            sensitivity.acceleration(),
            sensitivity.multipliers(),
        );
        let has_frames = self.rules.iter().any(|r| matches!(r, Rule::Frame { .. }));
        if has_frames {
            forward_kinematics(&system.model, &mut system.data, state.q.as_slice());
        }
        let mut jacobian_link = None;
        for (o, rule) in self.rules.iter().enumerate() {
            let row = &mut out[o * d..(o + 1) * d];
            match *rule {
                Rule::Coordinate(i) => (0..d).for_each(|j| row[j] = s_q[(i, j)]),
                Rule::Velocity(i) => (0..d).for_each(|j| row[j] = self.velocity[(i, j)]),
                Rule::Acceleration(i) => (0..d).for_each(|j| row[j] = s_qdd[(i, j)]),
                Rule::Multiplier { row: r, sign } => {
                    (0..d).for_each(|j| row[j] = sign * s_lambda[(r, j)])
                }
                Rule::Frame { link, axis } => {
                    if jacobian_link != Some(link) {
                        link_origin_jacobian(
                            &system.model,
                            &system.data,
                            link,
                            &mut self.link_jacobian,
                        );
                        jacobian_link = Some(link);
                    }
                    for (j, value) in row.iter_mut().enumerate() {
                        *value = (0..s_q.nrows())
                            .map(|i| self.link_jacobian[(axis, i)] * s_q[(i, j)])
                            .sum();
                    }
                }
                Rule::BasePosition { joint, axis } => {
                    let (qi, vi) = (
                        system.model.joints[joint].q_index,
                        system.model.joints[joint].v_index,
                    );
                    let rotation = orientation(state.q.as_slice(), qi);
                    for (j, value) in row.iter_mut().enumerate() {
                        let linear = Vec3::new(s_q[(vi, j)], s_q[(vi + 1, j)], s_q[(vi + 2, j)]);
                        *value = (rotation * linear)[axis];
                    }
                }
                Rule::BaseRotation { joint, axis } => {
                    let (qi, vi) = (
                        system.model.joints[joint].q_index,
                        system.model.joints[joint].v_index,
                    );
                    let now = orientation(state.q.as_slice(), qi);
                    let start = orientation(start_q.as_slice(), qi);
                    let y = (start.inverse() * now).scaled_axis();
                    let (right, left) = (
                        so3_right_jacobian_inverse(&y),
                        so3_right_jacobian_inverse(&-y),
                    );
                    let s_q0 = sensitivity.start_position();
                    for (j, value) in row.iter_mut().enumerate() {
                        let turn = Vec3::new(s_q[(vi + 3, j)], s_q[(vi + 4, j)], s_q[(vi + 5, j)]);
                        let start_turn =
                            Vec3::new(s_q0[(vi + 3, j)], s_q0[(vi + 4, j)], s_q0[(vi + 5, j)]);
                        *value = (right * turn - left * start_turn)[axis];
                    }
                }
            }
        }
        if has_frames {
            self.add_frame_geometry(system, state.q.as_slice(), out)?;
        }
        Ok(())
    }

    /// Adds the direct dependence of frame positions on joint origins and axes: for each dimension
    /// that moves them, a 4-point central difference of forward kinematics at fixed `q` with the
    /// model moved by the dimension's natural step (no value moves by more than
    /// [`super::THETA_FD_RELATIVE_STEP`] of its scale; frames are linear in origin translations).
    fn add_frame_geometry(
        &mut self,
        system: &mut RobotSystem,
        q: &[f64],
        out: &mut [f64],
    ) -> Result<(), crate::integrate::IntegrateError> {
        let d = self.d;
        for j in 0..d {
            let directions = system.parameter_directions();
            if !directions.moves_frames(j) {
                continue;
            }
            let step = directions.natural_step(j);
            for (offset, weight) in FRAME_STENCIL {
                system
                    .set_parameter_offset(j, offset * step)
                    .map_err(|source| crate::integrate::IntegrateError::System {
                        t: 0.0,
                        step: 0,
                        call: "set_parameter_offset",
                        source,
                    })?;
                forward_kinematics(&system.model, &mut system.data, q);
                let w = weight / (12.0 * step);
                for (o, rule) in self.rules.iter().enumerate() {
                    if let Rule::Frame { link, axis } = *rule {
                        out[o * d + j] += w * world_from_link(&system.model, &system.data, link)
                            .translation[axis];
                    }
                }
            }
            system.set_parameter_offset(j, 0.0).map_err(|source| {
                crate::integrate::IntegrateError::System {
                    t: 0.0,
                    step: 0,
                    call: "set_parameter_offset",
                    source,
                }
            })?;
        }
        Ok(())
    }
}

/// [`central_difference_run_with`] with [`CENTRAL_DIFFERENCE_STEP_XI`] and
/// [`central_difference_settings`].
pub fn central_difference_run(
    model: Model,
    environment: Environment,
    scene: &Scene,
    space: &ParameterSpace,
    xi: &[f64],
) -> Result<SensitivityRun, SensitivityRunError> {
    central_difference_run_with(
        model,
        environment,
        scene,
        space,
        xi,
        CENTRAL_DIFFERENCE_STEP_XI,
        central_difference_settings(scene),
    )
}

/// The outputs at `xi` and their derivatives by central differences of whole runs, `2d + 1` runs:
/// `∂y/∂ξ_j ≈ (y(ξ + h e_j) − y(ξ − h e_j)) / 2h` with `h = step_xi` (the checked fallback of
/// [`sensitivity_run`]; the points may leave the box by `h`). `model` as for
/// [`sensitivity_run_with`]; the values reported are those of the run at `xi` with `settings`.
///
/// Errors: a bad point or step; the first failing run, named.
pub fn central_difference_run_with(
    model: Model,
    environment: Environment,
    scene: &Scene,
    space: &ParameterSpace,
    xi: &[f64],
    step_xi: f64,
    settings: HhtSettings,
) -> Result<SensitivityRun, SensitivityRunError> {
    check_point(space, xi)?;
    if !(step_xi.is_finite() && step_xi > 0.0) {
        return Err(SensitivityRunError::InvalidStep { step: step_xi });
    }
    let d = space.len();
    let (times, values, nominal) = plain_run(&model, &environment, scene, space, xi, settings)
        .map_err(|source| SensitivityRunError::Simulation {
            run: "the run at ξ".to_string(),
            source,
        })?;
    let n_outputs = scene.outputs.len();
    let mut jacobian = vec![0.0; values.len() * d];
    let mut newton_iterations = nominal.newton_iterations;
    let mut point = xi.to_vec();
    for j in 0..d {
        let mut runs = Vec::with_capacity(2);
        for sign in [1.0, -1.0] {
            point[j] = xi[j] + sign * step_xi;
            let (_, run, stats) = plain_run(&model, &environment, scene, space, &point, settings)
                .map_err(|source| SensitivityRunError::Simulation {
                run: format!(
                    "the run at ξ {} {step_xi} e_{j} ({})",
                    if sign > 0.0 { "+" } else { "-" },
                    space.dimensions()[j].name
                ),
                source,
            })?;
            newton_iterations += stats.newton_iterations;
            runs.push(run);
        }
        point[j] = xi[j];
        for (i, (plus, minus)) in runs[0].iter().zip(&runs[1]).enumerate() {
            jacobian[i * d + j] = (plus - minus) / (2.0 * step_xi);
        }
    }
    debug_assert_eq!(values.len(), times.len() * n_outputs);
    Ok(SensitivityRun {
        times,
        outputs: scene.outputs.clone(),
        dimensions: space.dimensions().iter().map(|x| x.name.clone()).collect(),
        xi: xi.to_vec(),
        values,
        jacobian,
        stats: SensitivityRunStats {
            runs: 2 * d + 1,
            nominal,
            newton_iterations,
            sensitivity: None,
        },
    })
}

/// One plain run at `point`: record times, values (record-major) and statistics.
fn plain_run(
    model: &Model,
    environment: &Environment,
    scene: &Scene,
    space: &ParameterSpace,
    point: &[f64],
    settings: HhtSettings,
) -> Result<(Vec<f64>, Vec<f64>, HhtStats), SimulationError> {
    let mut system = system_at(model.clone(), *environment, scene, space, point);
    let violation = initial_violation(&mut system, scene);
    let constraints = system.constraints.clone();
    let failed = |e| SimulationError::from_integrate(e, &constraints, violation);
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let mut integrator =
        HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).map_err(failed)?;
    let recorder = Recorder::new(&scene.outputs);
    let initial = Recorder::initial_orientations(&system.model, integrator.state().q.as_slice());
    let n_records = scene.n_steps / scene.record_every + 2;
    let mut times = Vec::with_capacity(n_records);
    let mut values = Vec::with_capacity(n_records * scene.outputs.len());
    let mut row = vec![0.0; scene.outputs.len()];
    for k in 0..=scene.n_steps {
        if k > 0 {
            integrator.step(&mut system).map_err(failed)?;
        }
        if scene.records_step(k) {
            times.push(record_current_state(
                &recorder,
                &mut system,
                &integrator,
                &initial,
                &mut row,
            ));
            values.extend_from_slice(&row);
        }
    }
    Ok((times, values, *integrator.stats()))
}
