//! The parameter space of a study: the sidecar's `[parameters]` and `[bind]` resolved against a model.
//!
//! (`[parameters]`, `[bind]`, model) ⇒ (dimensions of ξ, bound paths, warnings)

use super::consistency::check_box;
use super::error::UncertaintyError;
use super::expression::{Expression, ExpressionError, SQRT};
use crate::model::Model;
use crate::params::{self, ParamTarget};
use crate::scene::SidecarFile;
use crate::text::closest_suggestion;

/// Relative tolerance for "a binding reproduces the URDF value at the symbols' midpoints": the
/// expression and the URDF file may round the same number differently in the last digits.
pub const BIND_NOMINAL_RELATIVE_TOLERANCE: f64 = 1e-9;

/// What one dimension of ξ moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DimensionKind {
    /// A model value, written directly.
    Path(ParamTarget),
    /// A free symbol, which moves the model only through `[bind]` expressions.
    Symbol,
}

/// One interval parameter: dimension `i` of ξ, `x_i = c_i + r_i ξ_i` with `ξ_i ∈ [-1, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Dimension {
    /// The key as written: a parameter path (`link.forearm_link.mass`) or a symbol name (`l1`).
    pub name: String,
    /// Lower bound `x̲_i` (the parameter's unit).
    pub lower: f64,
    /// Upper bound `x̄_i` (> `lower`).
    pub upper: f64,
    /// The nominal value: the URDF value of a path, the midpoint of a symbol.
    pub nominal: f64,
    /// What the dimension moves.
    pub kind: DimensionKind,
}

impl Dimension {
    /// The midpoint `c_i = (x̲_i + x̄_i) / 2`.
    pub fn center(&self) -> f64 {
        0.5 * (self.lower + self.upper)
    }

    /// The radius `r_i = (x̄_i − x̲_i) / 2`.
    pub fn radius(&self) -> f64 {
        0.5 * (self.upper - self.lower)
    }

    /// The physical value at `xi` (`ξ_i ∈ [-1, 1]`): `c_i + r_i ξ_i`, computed as the convex
    /// combination `((1 − ξ) x̲ + (1 + ξ) x̄) / 2` so that the bounds are hit exactly at ξ = ±1
    /// (a mass bound of 0 stays 0, never −1e-17).
    #[inline]
    pub fn value_at(&self, xi: f64) -> f64 {
        0.5 * ((1.0 - xi) * self.lower + (1.0 + xi) * self.upper)
    }

    /// The ξ of a physical value: `(x − c_i) / r_i`.
    pub fn xi_of(&self, value: f64) -> f64 {
        (value - self.center()) / self.radius()
    }
}

/// A model value bound to an expression of the free symbols (`[bind]`).
#[derive(Clone, Debug, PartialEq)]
pub struct Binding {
    /// The parameter path as written.
    pub path: String,
    /// The value it writes.
    pub target: ParamTarget,
    /// The expression; its symbol `k` is dimension `k` (always a [`DimensionKind::Symbol`]).
    pub expression: Expression,
}

impl Binding {
    /// The expression's value at `xi` (`xi: dim d`). Allocates nothing.
    #[inline]
    pub fn value_at(&self, dimensions: &[Dimension], xi: &[f64]) -> f64 {
        self.expression
            .eval(&|k: usize| dimensions[k].value_at(xi[k]))
    }
}

/// The interval parameters of a study, resolved against one model and checked for physical
/// consistency of the whole box. See the [module documentation](super).
#[derive(Clone, Debug)]
pub struct ParameterSpace {
    dimensions: Vec<Dimension>,
    bindings: Vec<Binding>,
    warnings: Vec<String>,
}

/// `[table] "key"`, the way messages name a sidecar key.
pub(super) fn key_label(table: &str, key: &str) -> String {
    format!("[{table}] \"{key}\"")
}

/// Whether `key` can be a free symbol: `[A-Za-z_][A-Za-z0-9_]*`.
pub fn is_symbol_name(key: &str) -> bool {
    let mut chars = key.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The ways `[parameters]` can give an interval.
enum IntervalForm {
    Bounds(f64, f64),
    Relative(f64),
    Absolute(f64),
}

const FORMS: &str =
    "write [lower, upper], { rel = fraction } (±fraction of the URDF value) or { abs = amount }";

fn number(value: &toml::Value) -> Option<f64> {
    match value {
        toml::Value::Float(x) => Some(*x),
        // Whole numbers in TOML (`[2, 3]`) are bounds too; i64 → f64 is exact up to 2^53.
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

fn read_form(value: &toml::Value) -> Result<IntervalForm, String> {
    match value {
        toml::Value::Array(items) => match items.as_slice() {
            [lower, upper] => match (number(lower), number(upper)) {
                (Some(lower), Some(upper)) => Ok(IntervalForm::Bounds(lower, upper)),
                _ => Err(format!("bounds must be numbers; {FORMS}")),
            },
            _ => Err(format!(
                "an interval has two bounds, not {}; {FORMS}",
                items.len()
            )),
        },
        toml::Value::Table(table) => {
            let mut entries = table.iter();
            match (entries.next(), entries.next()) {
                (Some((name, amount)), None) if name == "rel" || name == "abs" => {
                    let Some(amount) = number(amount) else {
                        return Err(format!("'{name}' must be a number; {FORMS}"));
                    };
                    Ok(if name == "rel" {
                        IntervalForm::Relative(amount)
                    } else {
                        IntervalForm::Absolute(amount)
                    })
                }
                _ => Err(format!(
                    "an inline table holds exactly one key, rel or abs; {FORMS}"
                )),
            }
        }
        _ => Err(FORMS.to_string()),
    }
}

impl ParameterSpace {
    /// Resolves a parsed sidecar's `[parameters]` and `[bind]`; see [`ParameterSpace::from_tables`].
    pub fn from_sidecar(
        sidecar: &SidecarFile,
        model: &Model,
        file: &str,
    ) -> Result<ParameterSpace, UncertaintyError> {
        Self::from_tables(&sidecar.parameters, &sidecar.bind, model, file)
    }

    /// Resolves `[parameters]` (dimensions, in order of appearance) and `[bind]` (bound paths)
    /// against `model` (its values are the URDF values), then checks the physical consistency of
    /// the box ([`ParameterSpace::check_box`]). `file` names the sidecar in messages. Non-fatal
    /// findings are in [`ParameterSpace::warnings`].
    pub fn from_tables(
        parameters: &toml::Table,
        bind: &toml::Table,
        model: &Model,
        file: &str,
    ) -> Result<ParameterSpace, UncertaintyError> {
        let mut space = ParameterSpace {
            dimensions: Vec::with_capacity(parameters.len()),
            bindings: Vec::with_capacity(bind.len()),
            warnings: Vec::new(),
        };
        // Every declared target with its key, to refuse a value declared twice.
        let mut declared: Vec<(ParamTarget, String)> = Vec::new();
        for (key, value) in parameters {
            let dimension = read_dimension(key, value, model, file)?;
            if let DimensionKind::Path(target) = dimension.kind {
                check_unique(&declared, target, &key_label("parameters", key), file)?;
                declared.push((target, key_label("parameters", key)));
            }
            space.dimensions.push(dimension);
        }
        for (key, value) in bind {
            let binding = space.read_binding(key, value, model, file)?;
            check_unique(&declared, binding.target, &key_label("bind", key), file)?;
            declared.push((binding.target, key_label("bind", key)));
            space.bindings.push(binding);
        }
        for (k, dimension) in space.dimensions.iter().enumerate() {
            let used = space
                .bindings
                .iter()
                .any(|b| b.expression.symbols().contains(&k));
            if dimension.kind == DimensionKind::Symbol && !used {
                space.warnings.push(format!(
                    "{file}: {}: the free symbol is used by no [bind] expression, so it changes nothing; bind a path to it or remove it",
                    key_label("parameters", &dimension.name)
                ));
            }
        }
        let box_warnings = space.check_box(model, file)?;
        space.warnings.extend(box_warnings);
        Ok(space)
    }

    fn read_binding(
        &mut self,
        key: &str,
        value: &toml::Value,
        model: &Model,
        file: &str,
    ) -> Result<Binding, UncertaintyError> {
        let label = key_label("bind", key);
        let target =
            params::resolve(model, key).map_err(|e| UncertaintyError::BindKeyNotAPath {
                file: file.to_string(),
                key: label.clone(),
                reason: e.to_string(),
            })?;
        let Some(text) = value.as_str() else {
            return Err(UncertaintyError::BindNotAString {
                file: file.to_string(),
                key: label,
                value: value.to_string(),
            });
        };
        // Paths never parse as identifiers, so only symbols can match.
        let names: Vec<&str> = self.dimensions.iter().map(|d| d.name.as_str()).collect();
        let key_and_text = format!("{label} = \"{text}\"");
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
                    file: file.to_string(),
                    key: key_and_text.clone(),
                    hint: format!(
                        "{} (declared symbols: {declared})",
                        closest_suggestion(&name, symbols.iter().copied())
                    ),
                    name,
                }
            }
            source => UncertaintyError::BadExpression {
                file: file.to_string(),
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
        let urdf_value = params::get(model, target);
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

    /// The dimensions of ξ, in the sidecar's order of appearance (`d = self.dimensions().len()`).
    pub fn dimensions(&self) -> &[Dimension] {
        &self.dimensions
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

    /// Non-fatal findings: unused symbols, bindings that do not reproduce the URDF value, links whose
    /// URDF inertia is already unphysical, a box check that could not be exhaustive.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// ξ of the nominal point (`dim d`): for a path `(URDF value − c_i) / r_i`, which is not 0
    /// when the interval is not centred on the URDF value; 0 for a symbol.
    pub fn nominal_xi(&self) -> Vec<f64> {
        nominal_xi(&self.dimensions)
    }

    /// The physical values `x_i = c_i + r_i ξ_i` of every dimension (`xi: dim d`), e.g. to report
    /// the parameters of a failed sample.
    pub fn values_at(&self, xi: &[f64]) -> Vec<f64> {
        self.dimensions
            .iter()
            .zip(xi)
            .map(|(d, &x)| d.value_at(x))
            .collect()
    }

    /// Writes the point `xi` (`dim d`, each in [-1, 1]) into `model`: each path dimension's value and
    /// each binding's expression value, through [`params::set`]; then [`Model::refresh`].
    /// Overwrites exactly the declared values. Allocates nothing.
    ///
    /// # Panics
    /// When `xi.len()` is not `d` (a caller's bug).
    pub fn apply(&self, model: &mut Model, xi: &[f64]) {
        assert_eq!(
            xi.len(),
            self.dimensions.len(),
            "ξ has {} components, the parameter space {}",
            xi.len(),
            self.dimensions.len()
        );
        for (dimension, &x) in self.dimensions.iter().zip(xi) {
            if let DimensionKind::Path(target) = dimension.kind {
                params::set(model, target, dimension.value_at(x));
            }
        }
        for binding in &self.bindings {
            params::set(
                model,
                binding.target,
                binding.value_at(&self.dimensions, xi),
            );
        }
        model.refresh();
    }

    /// Checks the physical consistency of the whole box against `model`'s (URDF) values; returns
    /// warnings. The [module documentation](super) says what is and is not guaranteed.
    pub fn check_box(&self, model: &Model, file: &str) -> Result<Vec<String>, UncertaintyError> {
        check_box(&self.dimensions, &self.bindings, model, file)
    }
}

/// ξ of the nominal point of `dimensions` (see [`ParameterSpace::nominal_xi`]).
pub(super) fn nominal_xi(dimensions: &[Dimension]) -> Vec<f64> {
    dimensions
        .iter()
        .map(|d| match d.kind {
            DimensionKind::Path(_) => d.xi_of(d.nominal),
            DimensionKind::Symbol => 0.0,
        })
        .collect()
}

fn check_unique(
    declared: &[(ParamTarget, String)],
    target: ParamTarget,
    label: &str,
    file: &str,
) -> Result<(), UncertaintyError> {
    match declared.iter().find(|(t, _)| *t == target) {
        Some((_, other)) => Err(UncertaintyError::Duplicate {
            file: file.to_string(),
            key: label.to_string(),
            other: other.clone(),
        }),
        None => Ok(()),
    }
}

/// One `[parameters]` entry as a dimension.
fn read_dimension(
    key: &str,
    value: &toml::Value,
    model: &Model,
    file: &str,
) -> Result<Dimension, UncertaintyError> {
    let label = key_label("parameters", key);
    let bad = |reason: String| UncertaintyError::BadInterval {
        file: file.to_string(),
        key: label.clone(),
        value: value.to_string(),
        reason,
    };
    let kind = match params::resolve(model, key) {
        Ok(target) => DimensionKind::Path(target),
        Err(_) if is_symbol_name(key) => {
            if key == SQRT {
                return Err(UncertaintyError::ReservedSymbol {
                    file: file.to_string(),
                    key: label,
                });
            }
            DimensionKind::Symbol
        }
        Err(e) => {
            return Err(UncertaintyError::UnknownKey {
                file: file.to_string(),
                key: label,
                reason: e.to_string(),
            })
        }
    };
    let form = read_form(value).map_err(bad)?;
    let urdf_value = match kind {
        DimensionKind::Path(target) => Some(params::get(model, target)),
        DimensionKind::Symbol => None,
    };
    let (lower, upper) = match (form, urdf_value) {
        (IntervalForm::Bounds(lower, upper), _) => (lower, upper),
        (_, None) => {
            return Err(bad(format!(
                "a free symbol has no URDF value, so it takes explicit bounds only: {key} = [lower, upper]"
            )))
        }
        (IntervalForm::Relative(rel), Some(u)) => {
            if !(rel.is_finite() && rel > 0.0) {
                return Err(bad(
                    "rel must be a finite fraction > 0 (0.01 is ±1 %)".to_string()
                ));
            }
            if u == 0.0 {
                return Err(UncertaintyError::RelativeOfZero {
                    file: file.to_string(),
                    key: label,
                    value: value.to_string(),
                });
            }
            (u - rel * u.abs(), u + rel * u.abs())
        }
        (IntervalForm::Absolute(amount), Some(u)) => {
            if !(amount.is_finite() && amount > 0.0) {
                return Err(bad(
                    "abs must be a finite amount > 0 (abs = 0 is no uncertainty: remove the entry, or use --set to change a value)".to_string(),
                ));
            }
            (u - amount, u + amount)
        }
    };
    if !(lower.is_finite() && upper.is_finite()) {
        return Err(bad("the bounds must be finite numbers".to_string()));
    }
    if lower > upper {
        return Err(bad(format!(
            "the lower bound is above the upper bound; write [{upper}, {lower}]"
        )));
    }
    if lower == upper {
        return Err(bad(
            "the interval has zero width, which is no uncertainty: widen it or remove the entry (use --set to change a value)".to_string(),
        ));
    }
    if let (DimensionKind::Path(target), Some(u)) = (kind, urdf_value) {
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
            params::validate_value(model, target, bound).map_err(|source| {
                UncertaintyError::ImpossibleBound {
                    file: file.to_string(),
                    key: label.clone(),
                    source,
                }
            })?;
        }
    }
    Ok(Dimension {
        name: key.to_string(),
        lower,
        upper,
        nominal: urdf_value.unwrap_or(0.5 * (lower + upper)),
        kind,
    })
}
