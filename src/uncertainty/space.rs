//! The parameter space of a study: the sidecar's `[parameters]` and `[bind]` resolved against a model.
//!
//! (`[parameters]` expanded by [`crate::sidecar::expand_parameters`], `[bind]`, model) ⇒
//! (dimensions of ξ, shared groups, bound paths, warnings, notes)

use super::consistency::{check_box, inertia_about_com_in_link, BoxCheckSummary};
use super::dimension::{
    nominal_xi, Binding, Dimension, DimensionKind, Group, GroupMember, GroupMode,
};
use super::error::UncertaintyError;
use super::expression::{Expression, ExpressionError};
use crate::environment::Environment;
use crate::model::Model;
use crate::params::{self, ParamTarget};
use crate::sidecar::{
    expand_parameters, key_label, located, BindDeclaration, EntryKind, IntervalForm,
    ParameterEntry, SidecarFile,
};
use crate::text::closest_suggestion;
use std::collections::hash_map::Entry;
use std::collections::HashMap;

/// Relative tolerance for "a binding reproduces the URDF value at the symbols' midpoints": the
/// expression and the URDF file may round the same number differently in the last digits.
pub const BIND_NOMINAL_RELATIVE_TOLERANCE: f64 = 1e-9;

/// The interval parameters of a study, resolved against one model and checked for physical
/// consistency of the whole box. See the [module documentation](super).
#[derive(Clone, Debug)]
pub struct ParameterSpace {
    dimensions: Vec<Dimension>,
    groups: Vec<Group>,
    bindings: Vec<Binding>,
    warnings: Vec<String>,
    notes: Vec<String>,
    box_check: BoxCheckSummary,
    /// The sidecar file, for messages.
    file: String,
    /// The links whose inertia a `[bind]` expression moves and whose URDF inertia is physical:
    /// checked again at every point a study applies ([`ParameterSpace::check_bound_values`]).
    bound_inertia_links: Vec<usize>,
}

impl ParameterSpace {
    /// Expands the sidecar's `[parameters]` ([`crate::sidecar::expand_parameters`]: paths,
    /// symbols, patterns), resolves its entries (dimensions, in that order) and `[bind]` (bound
    /// paths) against `model` and `environment` (their values are the URDF's and the scene's), then checks the physical
    /// consistency of the box ([`ParameterSpace::check_box`]). `file` names the sidecar in
    /// messages. Non-fatal findings are in [`ParameterSpace::warnings`], the expansion's decisions
    /// in [`ParameterSpace::notes`].
    pub fn from_sidecar(
        sidecar: &SidecarFile,
        model: &Model,
        environment: &Environment,
        file: &str,
    ) -> Result<ParameterSpace, UncertaintyError> {
        let (parameters, bind) = (&sidecar.parameters, &sidecar.bind);
        let expanded = expand_parameters(parameters, bind, model, environment, file)?;
        let mut space = ParameterSpace {
            dimensions: Vec::with_capacity(expanded.entries.len()),
            groups: Vec::new(),
            bindings: Vec::with_capacity(bind.len()),
            warnings: Vec::new(),
            notes: expanded.notes,
            box_check: BoxCheckSummary::default(),
            file: file.to_string(),
            bound_inertia_links: Vec::new(),
        };
        // Every declared target with the key that declared it first, to refuse a value declared
        // twice (a map: a list searched per key made a box of every link quadratic).
        let mut declared: HashMap<ParamTarget, String> = HashMap::new();
        for entry in &expanded.entries {
            // Messages about the entry point at its key's line.
            let at = located(file, entry.line);
            let dimension = space.read_dimension(entry, model, environment, &at)?;
            let label = dimension_label(entry);
            match dimension.kind {
                DimensionKind::Path(target) => declare(&mut declared, target, label, &at)?,
                DimensionKind::Group(g) => {
                    for member in &space.groups[g].members {
                        declare(&mut declared, member.target, label.clone(), &at)?;
                    }
                }
                DimensionKind::Symbol => {}
            }
            space.dimensions.push(dimension);
        }
        for declaration in bind {
            let at = located(file, declaration.line);
            let binding = space.read_binding(declaration, model, environment, file)?;
            declare(
                &mut declared,
                binding.target,
                key_label("bind", &declaration.key),
                &at,
            )?;
            space.bindings.push(binding);
        }
        let mut used = vec![false; space.dimensions.len()];
        for binding in &space.bindings {
            for &k in binding.expression.symbols() {
                used[k] = true;
            }
        }
        for (k, dimension) in space.dimensions.iter().enumerate() {
            if dimension.kind == DimensionKind::Symbol && !used[k] {
                space.warnings.push(format!(
                    "{file}: {}: the free symbol is used by no [bind] expression, so it changes nothing; bind a path to it or remove it",
                    key_label("parameters", &dimension.name)
                ));
            }
        }
        let (box_warnings, summary) = check_box(
            &space.dimensions,
            &space.groups,
            &space.bindings,
            model,
            file,
        )?;
        space.warnings.extend(box_warnings);
        space.box_check = summary;
        space.bound_inertia_links = bound_inertia_links(&space.bindings, model);
        Ok(space)
    }

    fn read_binding(
        &mut self,
        declaration: &BindDeclaration,
        model: &Model,
        environment: &Environment,
        file: &str,
    ) -> Result<Binding, UncertaintyError> {
        let key = declaration.key.as_str();
        let label = key_label("bind", key);
        // Errors about the key point at its line (the warning below names the file alone).
        let at = located(file, declaration.line);
        let target = params::resolve(model, environment, key).map_err(|e| {
            UncertaintyError::BindKeyNotAPath {
                file: at.clone(),
                key: label.clone(),
                reason: e.to_string(),
            }
        })?;
        let text = match &declaration.expression {
            Ok(text) => text.as_str(),
            Err(value) => {
                return Err(UncertaintyError::BindNotAString {
                    file: at.clone(),
                    key: label,
                    value: value.clone(),
                })
            }
        };
        // Paths and pattern keys never parse as identifiers, so only symbols can match.
        let names: Vec<&str> = self.dimensions.iter().map(|d| d.name.as_str()).collect();
        let key_and_text = format!("{label} = {}", quoted_excerpt(text));
        let expression = Expression::parse(text, &names).map_err(|source| match source {
            ExpressionError::UnknownSymbol { name, .. } => {
                let symbols: Vec<&str> = self
                    .dimensions
                    .iter()
                    .filter(|d| d.kind == DimensionKind::Symbol)
                    .map(|d| d.name.as_str())
                    .collect();
                let declared = if symbols.is_empty() {
                    "none".to_string()
                } else {
                    symbols.join(", ")
                };
                UncertaintyError::UnknownSymbol {
                    file: at.clone(),
                    key: key_and_text.clone(),
                    hint: format!(
                        "{} (declared symbols: {declared})",
                        closest_suggestion(&name, symbols.iter().copied())
                    ),
                    name,
                }
            }
            source => UncertaintyError::BadExpression {
                file: at.clone(),
                key: key_and_text.clone(),
                source,
            },
        })?;
        let binding = Binding {
            path: key.to_string(),
            target,
            expression,
        };
        // The symbols' midpoints are their nominals.
        let at_midpoints = binding
            .expression
            .eval(&|k: usize| self.dimensions[k].nominal);
        let urdf_value = params::get(model, environment, target);
        let scale = urdf_value.abs().max(at_midpoints.abs());
        // Written so that a NaN counts as a mismatch.
        let reproduces =
            (at_midpoints - urdf_value).abs() <= BIND_NOMINAL_RELATIVE_TOLERANCE * scale;
        if !reproduces {
            self.warnings.push(format!(
                "{file}: {label} = \"{text}\": the URDF value is {urdf_value} but the expression gives {at_midpoints} at the symbols' midpoints; the nominal run uses the expression's value"
            ));
        }
        Ok(binding)
    }

    /// One expanded `[parameters]` entry as a dimension (a group is stored in `self.groups`).
    fn read_dimension(
        &mut self,
        entry: &ParameterEntry,
        model: &Model,
        environment: &Environment,
        file: &str,
    ) -> Result<Dimension, UncertaintyError> {
        let label = dimension_label(entry);
        let bad = |reason: String| UncertaintyError::BadInterval {
            file: file.to_string(),
            key: label.clone(),
            value: entry.value.clone(),
            reason,
        };
        let name = entry.name().to_string();
        let source = entry.source.clone();
        let impossible = |source: params::ParamError| UncertaintyError::ImpossibleBound {
            file: file.to_string(),
            key: label.clone(),
            source,
        };
        let target = match &entry.kind {
            EntryKind::Symbol => {
                let IntervalForm::Bounds(lower, upper) = entry.interval.form else {
                    return Err(bad(format!(
                        "a free symbol has no URDF value, so it takes explicit bounds only: {name} = [lower, upper]"
                    )));
                };
                return Ok(Dimension {
                    name,
                    source,
                    unit: "",
                    lower,
                    upper,
                    nominal: 0.5 * (lower + upper),
                    kind: DimensionKind::Symbol,
                });
            }
            EntryKind::Group { members, unit } => {
                let (mode, amount, lower, upper, nominal) = match entry.interval.form {
                    IntervalForm::Relative(rel) => {
                        (GroupMode::Factor, rel, 1.0 - rel, 1.0 + rel, 1.0)
                    }
                    IntervalForm::Absolute(abs) => (GroupMode::Offset, abs, -abs, abs, 0.0),
                    IntervalForm::Bounds(..) => {
                        return Err(bad(
                            "a shared group takes { rel = … } or { abs = … }".to_string()
                        ))
                    }
                };
                let group = Group {
                    mode,
                    amount,
                    members: members
                        .iter()
                        .map(|(path, target)| GroupMember {
                            path: path.clone(),
                            target: *target,
                            urdf_value: params::get(model, environment, *target),
                        })
                        .collect(),
                };
                // Every member must be possible at both extremes (the members are affine in ξ).
                for member in &group.members {
                    for xi in [-1.0, 1.0] {
                        params::validate_value(
                            model,
                            member.target,
                            group.member_value(member, xi),
                        )
                        .map_err(impossible)?;
                    }
                }
                self.groups.push(group);
                return Ok(Dimension {
                    name,
                    source,
                    unit,
                    lower,
                    upper,
                    nominal,
                    kind: DimensionKind::Group(self.groups.len() - 1),
                });
            }
            EntryKind::Path { target, .. } => *target,
        };
        let u = params::get(model, environment, target);
        let (lower, upper) = match entry.interval.form {
            IntervalForm::Bounds(lower, upper) => (lower, upper),
            IntervalForm::Relative(rel) => {
                if u == 0.0 {
                    return Err(UncertaintyError::RelativeOfZero {
                        file: file.to_string(),
                        key: label,
                        value: entry.value.clone(),
                    });
                }
                (u - rel * u.abs(), u + rel * u.abs())
            }
            IntervalForm::Absolute(amount) => (u - amount, u + amount),
        };
        if !(lower.is_finite() && upper.is_finite()) {
            return Err(bad("the bounds must be finite numbers".to_string()));
        }
        if lower >= upper {
            return Err(bad(format!(
                "the interval [{lower}, {upper}] around the URDF value {u} is empty at f64 precision; widen it"
            )));
        }
        if !(lower <= u && u <= upper) {
            return Err(UncertaintyError::UrdfValueOutside {
                file: file.to_string(),
                key: label,
                lower,
                upper,
                urdf_value: u,
            });
        }
        for bound in [lower, upper] {
            params::validate_value(model, target, bound).map_err(impossible)?;
        }
        Ok(Dimension {
            name,
            source,
            unit: params::unit_of(model, target),
            lower,
            upper,
            nominal: u,
            kind: DimensionKind::Path(target),
        })
    }

    /// The dimensions of ξ, in the sidecar's order of appearance, patterns expanded in place
    /// (`d = self.dimensions().len()`).
    pub fn dimensions(&self) -> &[Dimension] {
        &self.dimensions
    }

    /// The shared groups ([`DimensionKind::Group`] indexes this list).
    pub fn groups(&self) -> &[Group] {
        &self.groups
    }

    /// The number of dimensions `d`.
    pub fn len(&self) -> usize {
        self.dimensions.len()
    }

    /// Whether there is no interval parameter at all.
    pub fn is_empty(&self) -> bool {
        self.dimensions.is_empty()
    }

    /// The model values bound to expressions (`[bind]`, in order of appearance).
    pub fn bindings(&self) -> &[Binding] {
        &self.bindings
    }

    /// The sidecar file the space was read from (as named in messages).
    pub fn sidecar_file(&self) -> &str {
        &self.file
    }

    /// The links whose inertia a binding moves and whose URDF inertia is physical.
    pub(super) fn bound_inertia_links(&self) -> &[usize] {
        &self.bound_inertia_links
    }

    /// Non-fatal findings: unused symbols, bindings that do not reproduce the URDF value, links whose
    /// URDF inertia is already unphysical, a box check that could not be exhaustive.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// What the expansion of patterns decided: explicit keys and `[bind]` paths overriding a
    /// pattern's match, a later pattern taking matches from an earlier one, zero values skipped by
    /// `rel` patterns, links without dynamics not matched by `link.*` patterns.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// What the box check visited when the space was built (for reports and tests).
    pub fn box_check(&self) -> BoxCheckSummary {
        self.box_check
    }

    /// ξ of the nominal point (`dim d`): for a path `(URDF value − c_i) / r_i`, which is not 0
    /// when the interval is not centred on the URDF value; 0 for a symbol and a group.
    pub fn nominal_xi(&self) -> Vec<f64> {
        nominal_xi(&self.dimensions)
    }

    /// The physical values `x_i = c_i + r_i ξ_i` of every dimension (`xi: dim d`), e.g. to report
    /// the parameters of a failed sample (a group's value is its factor or offset).
    pub fn values_at(&self, xi: &[f64]) -> Vec<f64> {
        self.dimensions
            .iter()
            .zip(xi)
            .map(|(d, &x)| d.value_at(x))
            .collect()
    }

    /// Writes the point `xi` (`dim d`, each in [-1, 1]) into `model` and `environment`: each path dimension's value,
    /// each group member's value and each binding's expression value, through [`params::set`];
    /// then [`Model::refresh`]. Overwrites exactly the declared values. Allocates nothing; the cost
    /// is linear in the number of values written.
    ///
    /// # Panics
    /// When `xi.len()` is not `d` (a caller's bug).
    pub fn apply(&self, model: &mut Model, environment: &mut Environment, xi: &[f64]) {
        assert_eq!(
            xi.len(),
            self.dimensions.len(),
            "ξ has {} components, the parameter space {}",
            xi.len(),
            self.dimensions.len()
        );
        for (dimension, &x) in self.dimensions.iter().zip(xi) {
            match dimension.kind {
                DimensionKind::Path(target) => {
                    params::set(model, environment, target, dimension.value_at(x))
                }
                DimensionKind::Group(g) => {
                    let group = &self.groups[g];
                    for member in &group.members {
                        params::set(
                            model,
                            environment,
                            member.target,
                            group.member_value(member, x),
                        );
                    }
                }
                DimensionKind::Symbol => {}
            }
        }
        for binding in &self.bindings {
            params::set(
                model,
                environment,
                binding.target,
                binding.value_at(&self.dimensions, xi),
            );
        }
        model.refresh();
    }

    /// Every model value that dimension `dimension` moves, with `∂value/∂ξ_dimension` at `xi`
    /// (`xi: dim d`), written into `out` (cleared first; it keeps its capacity; docs/method.md §1):
    /// - a path dimension: one entry, its radius `r_i` (exact);
    /// - a shared group: one entry per member, `u · amount` (factor) or `amount` (offset), exact;
    /// - a free symbol: one entry per `[bind]` expression that uses it, by central differences in
    ///   ξ with Richardson extrapolation ([`BIND_DERIVATIVE_STEP`](super::BIND_DERIVATIVE_STEP); about 1e-12 relative for smooth
    ///   expressions; at the faces of the box a one-sided difference into the box, about 1e-9).
    ///
    /// Values written through `link.NAME.scale` appear as [`ParamTarget::LinkScale`] entries: the
    /// link's effective mass and inertia are the description's values times the scale.
    ///
    /// # Panics
    /// When `xi.len()` is not `d` or `dimension ≥ d` (a caller's bug).
    pub fn target_derivatives(
        &self,
        xi: &[f64],
        dimension: usize,
        out: &mut Vec<(ParamTarget, f64)>,
    ) {
        assert_eq!(
            xi.len(),
            self.dimensions.len(),
            "ξ has {} components, the parameter space {}",
            xi.len(),
            self.dimensions.len()
        );
        out.clear();
        let d = &self.dimensions[dimension];
        match d.kind {
            DimensionKind::Path(target) => out.push((target, d.radius())),
            DimensionKind::Group(g) => {
                let group = &self.groups[g];
                out.extend(
                    group
                        .members
                        .iter()
                        .map(|m| (m.target, group.member_derivative(m))),
                );
            }
            DimensionKind::Symbol => {
                for binding in &self.bindings {
                    if binding.expression.symbols().contains(&dimension) {
                        out.push((
                            binding.target,
                            binding.derivative(&self.dimensions, xi, dimension),
                        ));
                    }
                }
            }
        }
    }

    /// Checks the physical consistency of the whole box against `model`'s (URDF) values; returns
    /// warnings. The [module documentation](super) says what is and is not guaranteed.
    pub fn check_box(&self, model: &Model, file: &str) -> Result<Vec<String>, UncertaintyError> {
        check_box(&self.dimensions, &self.groups, &self.bindings, model, file)
            .map(|(warnings, _)| warnings)
    }
}

/// How messages name an entry: `[parameters] "link.a.mass"`, or for a pattern's match
/// `[parameters] "link.*.mass" (match "link.a.mass")`.
fn dimension_label(entry: &ParameterEntry) -> String {
    let label = key_label("parameters", &entry.source);
    match &entry.kind {
        EntryKind::Path {
            path,
            from_pattern: true,
            ..
        } => format!("{label} (match \"{path}\")"),
        _ => label,
    }
}

/// The links whose inertia some binding writes and whose URDF inertia is physical, in order
/// (a link whose URDF inertia already violates is only warned about, as by the box check).
fn bound_inertia_links(bindings: &[Binding], model: &Model) -> Vec<usize> {
    let mut links: Vec<usize> = bindings
        .iter()
        .filter_map(|b| match b.target {
            ParamTarget::LinkInertia(link, _) => Some(link),
            _ => None,
        })
        .filter(|&link| {
            crate::model::check_inertia(&inertia_about_com_in_link(
                &model.description.links[link].inertial,
            ))
            .is_none()
        })
        .collect();
    links.sort_unstable();
    links.dedup();
    links
}

/// Records that `label` declares `target`, refusing a target some key declared before.
fn declare(
    declared: &mut HashMap<ParamTarget, String>,
    target: ParamTarget,
    label: String,
    file: &str,
) -> Result<(), UncertaintyError> {
    match declared.entry(target) {
        Entry::Occupied(other) => Err(UncertaintyError::Duplicate {
            file: file.to_string(),
            key: label,
            other: other.get().clone(),
        }),
        Entry::Vacant(slot) => {
            slot.insert(label);
            Ok(())
        }
    }
}

/// Longest expression quoted whole in a message, characters; longer ones are quoted by their start
/// and end (a hostile 100 000-character expression must not become a 200 kB error message).
pub const QUOTED_EXPRESSION_MAX_CHARS: usize = 120;

/// `"text"`, or for a long one its first and last [`QUOTED_EXPRESSION_MAX_CHARS`]/2 characters
/// around "…", with the total length.
pub(super) fn quoted_excerpt(text: &str) -> String {
    let n = text.chars().count();
    if n <= QUOTED_EXPRESSION_MAX_CHARS {
        return format!("\"{text}\"");
    }
    let half = QUOTED_EXPRESSION_MAX_CHARS / 2;
    let head: String = text.chars().take(half).collect();
    let tail: String = text.chars().skip(n - half).collect();
    format!("\"{head} … {tail}\" ({n} characters)")
}
