//! Physical consistency of the whole parameter box (docs/method.md §6).
//!
//! (dimensions, bindings, URDF values) ⇒ (warnings) or the first point of the box that is impossible
//!
//! Two checks:
//! 1. every bound path's expression value is a possible value of its target
//!    ([`crate::params::validate_value`]: finite; masses, damping and friction ≥ 0), on the points
//!    described below (direct paths were checked at both bounds when the sidecar was read);
//! 2. for every link whose inertia tensor some parameter moves, the rotational inertia about its COM
//!    in the link frame, `R I Rᵀ` with `R = R(rpy)` of the `<inertial><origin>`, is positive
//!    semi-definite and its principal moments satisfy the triangle inequality
//!    ([`crate::model::check_inertia`]). Mass and COM do not enter this tensor, so only the six
//!    inertia values of the link matter. A link whose URDF inertia already violates is only
//!    warned about (the loader warns too); the check refuses only violations the box *creates*.
//!
//! Points: only the dimensions that move the checked quantity vary, the others stay at their
//! nominal — per link, so the cost grows with the number of links times `2^m` for the `m`
//! dimensions of the busiest link, not with `2^d`. When a link's inertia values are all direct
//! paths or members of shared groups (both affine in ξ; a group moving several links makes each
//! of them depend on that one dimension), `R I Rᵀ` is affine in them and both conditions are
//! convex (`I ⪰ 0` and `tr(I)/2 · 1 − I ⪰ 0`), so the `2^m` corners of those `m` dimensions are a
//! proof for the whole box. `link.NAME.scale` multiplies the whole tensor by a positive factor,
//! which changes neither condition, so it is not a dimension of this check (its values are
//! refused at ≤ 0 when read). With `[bind]` expressions (nonlinear) the check is
//! dense, not a proof: the corners, then a grid of [`DENSE_CHECK_POINTS_PER_DIMENSION`] points per
//! dimension (fewer when that would exceed [`DENSE_CHECK_MAX_POINTS`] points, down to the corners
//! alone; beyond that, a warning says the check covered only part of the corners). A violation
//! confined between grid points can be missed.
//!
//! Merged bodies are not checked separately: a sum of physical rigid-body inertias is physical, so
//! a body whose links all pass passes too.

use super::dimension::{nominal_xi, Binding, Dimension, DimensionKind, Group};
use super::error::UncertaintyError;
use crate::model::{check_inertia, InertialSpec, Model};
use crate::params::{self, ParamTarget};
use crate::sidecar::key_label;
use crate::spatial::{rotation_from_rpy, Mat3};

/// What the box check visited (see [`ParameterSpace::box_check`](super::ParameterSpace::box_check)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoxCheckSummary {
    /// Links whose inertia tensor some dimension moves and that were checked.
    pub links: usize,
    /// Inertia tensors evaluated over those links (corners, plus grid points for nonlinear
    /// bindings): with only affine dependence, `Σ_links 2^(dimensions moving the link)`.
    pub inertia_points: usize,
    /// Points at which `[bind]` values were validated.
    pub binding_points: usize,
}

/// Grid points per dimension of the dense check of nonlinear bindings (−1, −½, 0, ½, 1).
pub const DENSE_CHECK_POINTS_PER_DIMENSION: usize = 5;

/// At most this many points per checked quantity: `5^5 = 3125` fits, so up to five symbols on one
/// link get the full 5-point grid; more symbols get a coarser grid (at least the corners).
pub const DENSE_CHECK_MAX_POINTS: usize = 4096;

/// Which points of the box to visit: levels of ξ along the varying dimensions.
struct PointPlan {
    dimensions: Vec<usize>,
    levels: usize,
    corners: usize,
    truncated: bool,
}

impl PointPlan {
    fn new(dimensions: Vec<usize>, dense: bool) -> PointPlan {
        let m = u32::try_from(dimensions.len()).unwrap_or(u32::MAX);
        let fits = |n: usize| {
            n.checked_pow(m)
                .is_some_and(|p| p <= DENSE_CHECK_MAX_POINTS)
        };
        let mut levels = if dense {
            DENSE_CHECK_POINTS_PER_DIMENSION
        } else {
            2
        };
        while levels > 2 && !fits(levels) {
            levels -= 1;
        }
        let truncated = !fits(2);
        let corners = 2usize
            .checked_pow(m)
            .map_or(DENSE_CHECK_MAX_POINTS, |c| c.min(DENSE_CHECK_MAX_POINTS));
        PointPlan {
            dimensions,
            levels,
            corners,
            truncated,
        }
    }

    /// Calls `visit(xi, is_corner)` on the corners, then on the other grid points; only the plan's
    /// dimensions of `xi` change, and they are put back before an `Ok` return (so one buffer at
    /// the nominal serves every plan: a copy of the whole point per link made a box of every link
    /// quadratic). Returns the number of points visited.
    fn visit<F>(&self, xi: &mut [f64], mut visit: F) -> Result<usize, UncertaintyError>
    where
        F: FnMut(&[f64], bool) -> Result<(), UncertaintyError>,
    {
        let base: Vec<f64> = self.dimensions.iter().map(|&k| xi[k]).collect();
        let visited = self.visit_points(xi, &mut visit)?;
        for (&k, &value) in self.dimensions.iter().zip(&base) {
            xi[k] = value;
        }
        Ok(visited)
    }

    fn visit_points<F>(&self, xi: &mut [f64], visit: &mut F) -> Result<usize, UncertaintyError>
    where
        F: FnMut(&[f64], bool) -> Result<(), UncertaintyError>,
    {
        for corner in 0..self.corners {
            for (j, &k) in self.dimensions.iter().enumerate() {
                xi[k] = if (corner >> j) & 1 == 1 { 1.0 } else { -1.0 };
            }
            visit(xi, true)?;
        }
        let mut visited = self.corners;
        if self.levels <= 2 {
            return Ok(visited);
        }
        let total = self.levels.pow(self.dimensions.len() as u32);
        let step = 2.0 / (self.levels - 1) as f64;
        for index in 0..total {
            let mut rest = index;
            let mut is_corner = true;
            for &k in &self.dimensions {
                let level = rest % self.levels;
                rest /= self.levels;
                is_corner &= level == 0 || level == self.levels - 1;
                xi[k] = -1.0 + step * level as f64;
            }
            if !is_corner {
                visit(xi, false)?;
                visited += 1;
            }
        }
        Ok(visited)
    }
}

/// `name = value` for dimension `k` (paths quoted, symbols bare).
fn describe_dimension(dimension: &Dimension, xi: f64) -> String {
    let value = dimension.value_at(xi);
    match dimension.kind {
        DimensionKind::Path(_) | DimensionKind::Group(_) => {
            format!("\"{}\" = {value}", dimension.name)
        }
        DimensionKind::Symbol => format!("{} = {value}", dimension.name),
    }
}

fn describe_point(dimensions: &[Dimension], varying: &[usize], xi: &[f64]) -> String {
    if varying.is_empty() {
        return "every point of the box".to_string();
    }
    varying
        .iter()
        .map(|&k| describe_dimension(&dimensions[k], xi[k]))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The rotational inertia about the COM in the link frame: `R I Rᵀ` (kg·m²).
pub(super) fn inertia_about_com_in_link(inertial: &InertialSpec) -> Mat3 {
    let [ixx, ixy, ixz, iyy, iyz, izz] = inertial.inertia;
    let in_inertia_frame = Mat3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
    let rotation = rotation_from_rpy(inertial.rpy[0], inertial.rpy[1], inertial.rpy[2]);
    rotation * in_inertia_frame * rotation.transpose()
}

/// What moves one link's inertia tensor.
#[derive(Default)]
struct LinkInertiaParameters {
    /// Direct dimensions with their component (0..6: ixx ixy ixz iyy iyz izz).
    direct: Vec<(usize, usize)>,
    /// Group dimensions with the group, the member and its component.
    grouped: Vec<(usize, usize, usize, usize)>,
    /// Bindings (indices) with their component.
    bound: Vec<(usize, usize)>,
}

/// Runs both checks (module documentation); returns warnings and what was visited.
pub(super) fn check_box(
    dimensions: &[Dimension],
    groups: &[Group],
    bindings: &[Binding],
    model: &Model,
    file: &str,
) -> Result<(Vec<String>, BoxCheckSummary), UncertaintyError> {
    let mut warnings = Vec::new();
    let mut summary = BoxCheckSummary::default();
    // The point the plans vary, at the nominal between them.
    let mut xi = nominal_xi(dimensions);

    // 1. Bound values are possible values.
    for binding in bindings {
        let plan = PointPlan::new(binding.expression.symbols().to_vec(), true);
        summary.binding_points += plan.visit(&mut xi, |xi, _| {
            let value = binding.value_at(dimensions, xi);
            params::validate_value(model, binding.target, value).map_err(|e| {
                UncertaintyError::ImpossibleBoundValue {
                    file: file.to_string(),
                    key: format!(
                        "{} = \"{}\"",
                        key_label("bind", &binding.path),
                        binding.expression.source()
                    ),
                    value,
                    point: describe_point(dimensions, binding.expression.symbols(), xi),
                    reason: match e {
                        params::ParamError::InvalidValue { reason, .. } => reason,
                        _ => "not a possible value of this parameter",
                    },
                }
            })
        })?;
        if plan.truncated {
            warnings.push(truncation_warning(
                file,
                &format!("the values of {}", key_label("bind", &binding.path)),
                plan.corners,
            ));
        }
    }

    // 2. Link inertias. Skipped at no cost when no parameter moves an inertia value.
    let mut links: Vec<LinkInertiaParameters> = Vec::new();
    fn entry(links: &mut Vec<LinkInertiaParameters>, link: usize) -> &mut LinkInertiaParameters {
        if links.len() <= link {
            links.resize_with(link + 1, Default::default);
        }
        &mut links[link]
    }
    for (k, dimension) in dimensions.iter().enumerate() {
        match dimension.kind {
            DimensionKind::Path(ParamTarget::LinkInertia(link, component)) => {
                entry(&mut links, link).direct.push((k, component));
            }
            DimensionKind::Group(g) => {
                for (m, member) in groups[g].members.iter().enumerate() {
                    if let ParamTarget::LinkInertia(link, component) = member.target {
                        entry(&mut links, link).grouped.push((k, g, m, component));
                    }
                }
            }
            _ => {}
        }
    }
    for (b, binding) in bindings.iter().enumerate() {
        if let ParamTarget::LinkInertia(link, component) = binding.target {
            entry(&mut links, link).bound.push((b, component));
        }
    }
    for (link, parameters) in links.iter().enumerate() {
        if parameters.direct.is_empty()
            && parameters.grouped.is_empty()
            && parameters.bound.is_empty()
        {
            continue;
        }
        let spec = &model.description.links[link];
        let mut varying: Vec<usize> = parameters
            .direct
            .iter()
            .map(|&(k, _)| k)
            .chain(parameters.grouped.iter().map(|&(k, ..)| k))
            .collect();
        let mut keys: Vec<String> = Vec::new();
        for &k in &varying {
            let label = key_label("parameters", &dimensions[k].name);
            if !keys.contains(&label) {
                keys.push(label);
            }
        }
        for &(b, _) in &parameters.bound {
            keys.push(key_label("bind", &bindings[b].path));
            varying.extend_from_slice(bindings[b].expression.symbols());
        }
        varying.sort_unstable();
        varying.dedup();
        if let Some(violation) = check_inertia(&inertia_about_com_in_link(&spec.inertial)) {
            warnings.push(format!(
                "{file}: the URDF inertia of link '{}' {violation}; the box of {} was not checked for this link",
                spec.name,
                keys.join(", ")
            ));
            continue;
        }
        let plan = PointPlan::new(varying.clone(), !parameters.bound.is_empty());
        summary.links += 1;
        summary.inertia_points += plan.visit(&mut xi, |xi, is_corner| {
            let mut inertial = spec.inertial;
            for &(k, component) in &parameters.direct {
                inertial.inertia[component] = dimensions[k].value_at(xi[k]);
            }
            for &(k, g, m, component) in &parameters.grouped {
                let group = &groups[g];
                inertial.inertia[component] = group.member_value(&group.members[m], xi[k]);
            }
            for &(b, component) in &parameters.bound {
                inertial.inertia[component] = bindings[b].value_at(dimensions, xi);
            }
            let Some(violation) = check_inertia(&inertia_about_com_in_link(&inertial)) else {
                return Ok(());
            };
            let mut point = describe_point(dimensions, &varying, xi);
            if !parameters.bound.is_empty() {
                let bound: Vec<String> = parameters
                    .bound
                    .iter()
                    .map(|&(b, c)| format!("\"{}\" = {}", bindings[b].path, inertial.inertia[c]))
                    .collect();
                point = format!("{point} (giving {})", bound.join(", "));
            }
            Err(UncertaintyError::InconsistentInertia {
                file: file.to_string(),
                link: spec.name.clone(),
                point: format!(
                    "{} {point}",
                    if is_corner { "corner" } else { "grid point" }
                ),
                violation: violation.to_string(),
            })
        })?;
        if plan.truncated {
            warnings.push(truncation_warning(
                file,
                &format!("the inertia of link '{}'", spec.name),
                plan.corners,
            ));
        }
    }
    Ok((warnings, summary))
}

fn truncation_warning(file: &str, what: &str, points: usize) -> String {
    format!(
        "{file}: {what} depends on too many parameters to check every corner of the box; only {points} corners were checked"
    )
}
