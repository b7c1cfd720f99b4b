//! Bound values checked where they are used (docs/method.md §6): at every point a study applies
//! and at the symbol values `simulate --set` gives. The box check (`consistency.rs`) visits the
//! corners and a grid; an expression can still give a value no model can have between those
//! points (a root of a denominator, a negative stretch of a polynomial, a square root of a
//! negative number), and then the run names the `[bind]` key, its expression and the symbol values
//! — not only the mass matrix that turned non-finite downstream.

use super::consistency::inertia_about_com_in_link;
use super::dimension::{Binding, DimensionKind};
use super::error::{BoundValueSource, UncertaintyError};
use super::space::{quoted_excerpt, ParameterSpace};
use crate::environment::Environment;
use crate::model::{check_inertia, Model};
use crate::params::{self, ParamTarget};
use crate::sidecar::key_label;

impl ParameterSpace {
    /// Checks the bound values at the point `xi` (`dim d`), which [`ParameterSpace::apply`] has
    /// written into `model`: every `[bind]` value finite and possible
    /// ([`params::validate_value`]), and the inertia of every link a binding moves (whose URDF
    /// inertia is physical) a rigid body's. The error names the key, its expression and the
    /// symbol values. Allocates nothing when the values pass.
    pub fn check_bound_values(&self, model: &Model, xi: &[f64]) -> Result<(), UncertaintyError> {
        let dimensions = self.dimensions();
        self.check_bindings(
            model,
            &|k: usize| dimensions[k].value_at(xi[k]),
            BoundValueSource::Sample,
        )
    }

    /// The dimension of the free symbol `name`, if the sidecar declares one.
    pub fn symbol_index(&self, name: &str) -> Option<usize> {
        self.dimensions()
            .iter()
            .position(|d| d.kind == DimensionKind::Symbol && d.name == name)
    }

    /// Writes into `model` and `environment` every binding that uses a symbol of `values` (`(dimension, value)`, the
    /// symbols' own values, not ξ), with the other symbols at their nominal (midpoint), and
    /// refreshes it; the values are checked as [`ParameterSpace::check_bound_values`] checks a
    /// sample's, and `model` changes only when they pass. Returns the paths written. Bindings that
    /// use none of the symbols keep the model's values.
    pub fn apply_symbol_values(
        &self,
        model: &mut Model,
        environment: &mut Environment,
        values: &[(usize, f64)],
    ) -> Result<Vec<String>, UncertaintyError> {
        let dimensions = self.dimensions();
        let value_of = |k: usize| {
            values
                .iter()
                .rev()
                .find(|(j, _)| *j == k)
                .map_or(dimensions[k].nominal, |(_, v)| *v)
        };
        let uses_set = |b: &&Binding| {
            b.expression
                .symbols()
                .iter()
                .any(|k| values.iter().any(|(j, _)| j == k))
        };
        let mut trial = model.clone();
        let mut trial_environment = *environment;
        for binding in self.bindings().iter().filter(uses_set) {
            params::set(
                &mut trial,
                &mut trial_environment,
                binding.target,
                binding.expression.eval(&value_of),
            );
        }
        trial.refresh();
        self.check_bindings(&trial, &value_of, BoundValueSource::SetFlags)?;
        *model = trial;
        *environment = trial_environment;
        Ok(self
            .bindings()
            .iter()
            .filter(uses_set)
            .map(|b| b.path.clone())
            .collect())
    }

    fn check_bindings(
        &self,
        model: &Model,
        value_of: &dyn Fn(usize) -> f64,
        advice: BoundValueSource,
    ) -> Result<(), UncertaintyError> {
        for binding in self.bindings() {
            let value = binding.expression.eval(&|k: usize| value_of(k));
            if let Err(error) = params::validate_value(model, binding.target, value) {
                let reason = match error {
                    params::ParamError::InvalidValue { reason, .. } => reason,
                    _ => "not a possible value of this parameter",
                };
                return Err(UncertaintyError::BoundValueAt {
                    file: self.sidecar_file().to_string(),
                    key: key_with_expression(binding),
                    value,
                    point: symbol_values(self, binding.expression.symbols(), value_of),
                    reason,
                    advice,
                });
            }
        }
        for &link in self.bound_inertia_links() {
            let spec = &model.description.links[link];
            let Some(violation) = check_inertia(&inertia_about_com_in_link(&spec.inertial)) else {
                continue;
            };
            let writes_link =
                |b: &&Binding| matches!(b.target, ParamTarget::LinkInertia(l, _) if l == link);
            let on_link: Vec<&Binding> = self.bindings().iter().filter(writes_link).collect();
            let keys: Vec<String> = on_link.iter().map(|b| key_with_expression(b)).collect();
            let mut symbols: Vec<usize> = on_link
                .iter()
                .flat_map(|b| b.expression.symbols().iter().copied())
                .collect();
            symbols.sort_unstable();
            symbols.dedup();
            return Err(UncertaintyError::BoundInertiaAt {
                file: self.sidecar_file().to_string(),
                keys: keys.join(", "),
                link: spec.name.clone(),
                violation_at: format!("{violation} at {}", symbol_values(self, &symbols, value_of)),
                advice,
            });
        }
        Ok(())
    }
}

/// `[bind] "PATH" = "EXPRESSION"` (a long expression by its ends).
fn key_with_expression(binding: &Binding) -> String {
    format!(
        "{} = {}",
        key_label("bind", &binding.path),
        quoted_excerpt(binding.expression.source())
    )
}

/// `k = 0.34, m0 = 2` for the symbols `symbols` (dimensions) at `value_of`.
fn symbol_values(
    space: &ParameterSpace,
    symbols: &[usize],
    value_of: &dyn Fn(usize) -> f64,
) -> String {
    if symbols.is_empty() {
        return "every point (the expression uses no symbol)".to_string();
    }
    symbols
        .iter()
        .map(|&k| format!("{} = {}", space.dimensions()[k].name, value_of(k)))
        .collect::<Vec<_>>()
        .join(", ")
}
