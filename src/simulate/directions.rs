//! The chain from a study's box to the model values: for dimension `j` of ξ, every model value
//! `θ_t` it moves with `∂θ_t/∂ξ_j` (docs/sensitivities.md §8).
//!
//! **TEMPORARY — to be replaced.** Another change adds
//! `ParameterSpace::target_derivatives(xi, j, &mut Vec<(ParamTarget, f64)>)` to `uncertainty/` (with
//! shared groups and `link.NAME.scale`); when it lands, [`target_derivatives`] should call it and
//! this file should go. Until then it builds the same list from today's [`ParameterSpace`]: a path
//! dimension moves its target by its radius `r_j` per unit ξ_j (`x = c + r ξ`); a free symbol moves
//! every `[bind]` expression that uses it, differentiated by a 4-point central difference in ξ_j
//! ([`BIND_DERIVATIVE_STEP_XI`]).

use crate::params::ParamTarget;
use crate::uncertainty::{DimensionKind, ParameterSpace};

/// Step in ξ of the 4-point central difference of a `[bind]` expression: truncation ~h⁴/30 ≈ 3e-14
/// of the fifth derivative (expressions are polynomials or square roots of the symbols, smooth on
/// the scale of the box), rounding ~u·|value|/h ≈ 1e-13 of the value.
pub const BIND_DERIVATIVE_STEP_XI: f64 = 1e-3;

/// Writes into `out` (cleared first) every model value dimension `j` of `space` moves at the point
/// `xi` (dim d), with `∂θ/∂ξ_j` in the value's unit per unit ξ. Allocates (a copy of `xi`).
///
/// # Panics
/// When `j ≥ d` or `xi.len() ≠ d` (a caller's bug).
pub fn target_derivatives(
    space: &ParameterSpace,
    xi: &[f64],
    j: usize,
    out: &mut Vec<(ParamTarget, f64)>,
) {
    let dimensions = space.dimensions();
    assert_eq!(xi.len(), dimensions.len(), "ξ has the wrong dimension");
    out.clear();
    if let DimensionKind::Path(target) = dimensions[j].kind {
        out.push((target, dimensions[j].radius()));
    }
    let mut moved = xi.to_vec();
    let h = BIND_DERIVATIVE_STEP_XI;
    for binding in space.bindings() {
        if !binding.expression.symbols().contains(&j) {
            continue;
        }
        let mut at = |offset: f64| {
            moved[j] = xi[j] + offset;
            binding.value_at(dimensions, &moved)
        };
        let derivative = (-at(2.0 * h) + 8.0 * at(h) - 8.0 * at(-h) + at(-2.0 * h)) / (12.0 * h);
        out.push((binding.target, derivative));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{parse_description, LoadOptions, Model};

    #[test]
    fn paths_move_by_their_radius_and_symbols_through_their_bindings() {
        let urdf = r#"<robot name="r"><link name="w"/>
          <link name="bar"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
          <inertia ixx="0" ixy="0" ixz="0" iyy="0.08333333333333333" iyz="0" izz="0.08333333333333333"/></inertial></link>
          <joint name="j" type="revolute"><parent link="w"/><child link="bar"/><axis xyz="0 0 1"/>
          <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#;
        let model = Model::from_description(
            parse_description(urdf, "r.urdf").unwrap(),
            LoadOptions::default(),
            "r.urdf",
        )
        .unwrap();
        let parameters: toml::Table =
            toml::from_str("\"link.bar.mass\" = [0.9, 1.3]\nl = [0.9, 1.1]").unwrap();
        let bind: toml::Table = toml::from_str(
            "\"link.bar.inertia.iyy\" = \"l * l / 12\"\n\"link.bar.inertia.izz\" = \"l * l / 12\"",
        )
        .unwrap();
        let space = ParameterSpace::from_tables(&parameters, &bind, &model, "s.toml").unwrap();
        let xi = [0.2, -0.5];
        let mut out = Vec::new();
        target_derivatives(&space, &xi, 0, &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].0, ParamTarget::LinkMass(1));
        assert!((out[0].1 - 0.2).abs() < 1e-15);
        target_derivatives(&space, &xi, 1, &mut out);
        // l = 1 + 0.1 ξ = 0.95; d(l²/12)/dξ = 2 l · 0.1 / 12, for iyy and izz.
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].0, ParamTarget::LinkInertia(1, 3));
        assert_eq!(out[1].0, ParamTarget::LinkInertia(1, 5));
        for (_, derivative) in &out {
            assert!((derivative - 2.0 * 0.95 * 0.1 / 12.0).abs() < 1e-13);
        }
    }
}
