//! `[scene] step_control`, `tolerance`, `limit_restitution` and `newton_matrix`: how the integrator
//! chooses its step, what a joint-limit impact does (docs/step-control.md §3–§4) and whether the
//! Newton matrix is kept across steps (docs/method.md §5), checked before anything runs.

use super::budget::MIN_STEP_S;
use super::SceneError;
use crate::integrate::{StepControl, DEFAULT_STEP_HALVINGS, DEFAULT_STEP_TOLERANCE};
use crate::sidecar::SceneSection;

/// The step-control values of a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepControlValues {
    /// Fixed (default) or adaptive.
    pub control: StepControl,
    /// Local error tolerance of the adaptive step, rad or m per step.
    pub tolerance: f64,
    /// Coefficient of restitution of joint-limit impacts, `[0, 1]`.
    pub limit_restitution: f64,
    /// Sub-steps (adaptive, impact location) down to `h / 2^k`: [`DEFAULT_STEP_HALVINGS`], fewer
    /// when `h / 2^k` would fall below [`MIN_STEP_S`].
    pub max_step_halvings: u32,
    /// Whether the Newton factorisation is kept across steps (`newton_matrix = "reuse"`).
    pub reuse_newton_matrix: bool,
}

/// Reads and checks the keys of `section` for a scene with grid step `step_s` whose effects declare
/// `joint_limits` or not; `path` names the sidecar in messages.
pub(super) fn resolve(
    section: &SceneSection,
    joint_limits: bool,
    step_s: f64,
    path: &str,
) -> Result<StepControlValues, SceneError> {
    let invalid = |key: &str, message: String| SceneError::Invalid {
        path: path.to_string(),
        key: key.to_string(),
        message,
    };
    let control = match section.step_control.as_deref() {
        None | Some("fixed") => StepControl::Fixed,
        Some("adaptive") => StepControl::Adaptive,
        Some(other) => {
            return Err(invalid(
                "[scene] step_control",
                format!(
                    "unknown step control '{other}': use \"fixed\" (the default) or \"adaptive\""
                ),
            ))
        }
    };
    let tolerance = match section.tolerance {
        None => DEFAULT_STEP_TOLERANCE,
        Some(_) if control != StepControl::Adaptive => {
            return Err(invalid(
                "[scene] tolerance",
                "the tolerance is used only by the adaptive step: add step_control = \"adaptive\" or remove tolerance"
                    .to_string(),
            ))
        }
        Some(t) if t.is_finite() && t > 0.0 && t < 1.0 => t,
        Some(t) => {
            return Err(invalid(
                "[scene] tolerance",
                format!(
                    "{t} must be a finite local error per step in rad or m, > 0 and < 1 (default {DEFAULT_STEP_TOLERANCE:e})"
                ),
            ))
        }
    };
    let limit_restitution = match section.limit_restitution {
        None => 0.0,
        Some(_) if !joint_limits => {
            return Err(invalid(
                "[scene] limit_restitution",
                "joint-limit impacts need the 'joint_limits' effect: add it to effects or remove limit_restitution"
                    .to_string(),
            ))
        }
        Some(e) if (0.0..=1.0).contains(&e) => e,
        Some(e) => {
            return Err(invalid(
                "[scene] limit_restitution",
                format!("{e} must be in [0, 1]: 0 stops the joint at its limit, 1 returns its approach speed"),
            ))
        }
    };
    let reuse_newton_matrix = match section.newton_matrix.as_deref() {
        None | Some("fresh") => false,
        Some("reuse") => true,
        Some(other) => {
            return Err(invalid(
                "[scene] newton_matrix",
                format!(
                    "unknown choice '{other}': use \"fresh\" (the default: factorised every step) or \"reuse\" (kept across steps while Newton contracts well; unconstrained scenes without contacts only)"
                ),
            ))
        }
    };
    Ok(StepControlValues {
        control,
        tolerance,
        limit_restitution,
        max_step_halvings: halvings_above_min_step(step_s, DEFAULT_STEP_HALVINGS),
        reuse_newton_matrix,
    })
}

/// The largest `k ≤ wanted` with `step_s / 2^k ≥` [`MIN_STEP_S`] (0 when the step itself is at the
/// floor): sub-steps never go below the smallest step a scene may ask for.
pub fn halvings_above_min_step(step_s: f64, wanted: u32) -> u32 {
    let mut k = 0;
    while k < wanted && step_s / f64::from(1u32 << (k + 1)) >= MIN_STEP_S {
        k += 1;
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    fn section(text: &str) -> SceneSection {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn newton_matrix_is_fresh_unless_reuse_is_asked_for() {
        assert!(
            !resolve(&section(""), false, 1e-3, "s.toml")
                .unwrap()
                .reuse_newton_matrix
        );
        let fresh = section("newton_matrix = \"fresh\"");
        assert!(
            !resolve(&fresh, false, 1e-3, "s.toml")
                .unwrap()
                .reuse_newton_matrix
        );
        let reuse = section("newton_matrix = \"reuse\"");
        assert!(
            resolve(&reuse, false, 1e-3, "s.toml")
                .unwrap()
                .reuse_newton_matrix
        );
        let bad = section("newton_matrix = \"old\"");
        let message = resolve(&bad, false, 1e-3, "s.toml")
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("s.toml")
                && message.contains("[scene] newton_matrix")
                && message.contains("'old'"),
            "{message}"
        );
    }

    #[test]
    fn keys_are_checked_and_named() {
        let ok = resolve(&section(""), false, 1e-3, "s.toml").unwrap();
        assert_eq!(ok.control, StepControl::Fixed);
        assert_eq!(ok.limit_restitution, 0.0);
        // 1 ms / 2^19 = 1.9e-9 s ≥ 1e-9 s; / 2^20 would be below it.
        assert_eq!(ok.max_step_halvings, 19);
        let adaptive = resolve(
            &section("step_control = \"adaptive\"\ntolerance = 1e-5"),
            false,
            1e-3,
            "s.toml",
        )
        .unwrap();
        assert_eq!(adaptive.control, StepControl::Adaptive);
        assert_eq!(adaptive.tolerance, 1e-5);
        for (text, limits, key, needle) in [
            (
                "step_control = \"smart\"",
                false,
                "step_control",
                "unknown step control",
            ),
            (
                "tolerance = 1e-6",
                false,
                "tolerance",
                "only by the adaptive step",
            ),
            (
                "step_control = \"adaptive\"\ntolerance = -1.0",
                false,
                "tolerance",
                "> 0",
            ),
            (
                "step_control = \"adaptive\"\ntolerance = nan",
                false,
                "tolerance",
                "finite",
            ),
            (
                "limit_restitution = 0.5",
                false,
                "limit_restitution",
                "'joint_limits' effect",
            ),
            (
                "limit_restitution = 1.5",
                true,
                "limit_restitution",
                "in [0, 1]",
            ),
        ] {
            let message = resolve(&section(text), limits, 1e-3, "s.toml")
                .unwrap_err()
                .to_string();
            assert!(
                message.contains("s.toml") && message.contains(key),
                "{message}"
            );
            assert!(message.contains(needle), "{message}");
        }
    }

    #[test]
    fn sub_steps_stay_above_the_smallest_step() {
        assert_eq!(halvings_above_min_step(1e-9, 10), 0);
        assert_eq!(halvings_above_min_step(4e-9, 10), 2);
        assert_eq!(halvings_above_min_step(1.0, 20), 20);
    }
}
