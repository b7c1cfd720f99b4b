//! Resolving `[[scene.drive]]` and `[[scene.loop]]` against the robot into constraint rows.

use super::sidecar::{DriveSection, LoopSection};
use super::SceneError;
use crate::constraints::{ConstraintSet, Drive, LoopClosure, LoopKind, Profile, Spline};
use crate::model::{JointKind, Model, UrdfJointType};
use crate::spatial::Vec3;
use crate::text::closest_suggestion;

/// Below this norm a declared direction is treated as zero (or two directions as parallel).
const DIRECTION_TOLERANCE: f64 = 1e-9;

/// Builds the constraint set: the scene's loops, every URDF mimic joint, the scene's drives.
pub fn resolve(
    drives: &[DriveSection],
    loops: &[LoopSection],
    model: &Model,
    path: &str,
) -> Result<ConstraintSet, SceneError> {
    let invalid = |key: String, message: String| SceneError::Invalid {
        path: path.to_string(),
        key,
        message,
    };
    let mut resolved_loops = Vec::with_capacity(loops.len());
    for (index, section) in loops.iter().enumerate() {
        let key = format!("[[scene.loop]] #{} '{}'", index + 1, section.name);
        if loops[..index].iter().any(|l| l.name == section.name) {
            return Err(invalid(
                key,
                "this name is used by another loop".to_string(),
            ));
        }
        resolved_loops.push(resolve_loop(section, model).map_err(|message| invalid(key, message))?);
    }
    let mut resolved_drives = Vec::with_capacity(drives.len());
    for (index, section) in drives.iter().enumerate() {
        let name = section
            .name
            .clone()
            .unwrap_or_else(|| section.joint.clone());
        let key = format!("[[scene.drive]] #{} '{name}'", index + 1);
        if resolved_drives.iter().any(|d: &Drive| d.name == name) {
            return Err(invalid(
                key,
                "this name is used by another drive".to_string(),
            ));
        }
        let drive =
            resolve_drive(section, name, model).map_err(|message| invalid(key.clone(), message))?;
        if let Some(other) = resolved_drives
            .iter()
            .find(|d: &&Drive| d.q_index == drive.q_index)
        {
            return Err(invalid(
                key,
                format!("joint '{}' is already driven by '{}'; two drives on one joint are redundant rows", section.joint, other.name),
            ));
        }
        resolved_drives.push(drive);
    }
    Ok(ConstraintSet::new(
        resolved_loops,
        ConstraintSet::mimics_of(model),
        resolved_drives,
    ))
}

fn resolve_drive(section: &DriveSection, name: String, model: &Model) -> Result<Drive, String> {
    let joint = match model.joint_index(&section.joint) {
        Some(j) => &model.joints[j],
        None => {
            let is_fixed = model
                .description
                .joints
                .iter()
                .any(|j| j.name == section.joint && j.joint_type == UrdfJointType::Fixed);
            return Err(if is_fixed {
                format!(
                    "joint '{}' is fixed; only moving joints can be driven",
                    section.joint
                )
            } else {
                format!(
                    "unknown joint '{}'{}",
                    section.joint,
                    closest_suggestion(
                        &section.joint,
                        model.joints.iter().map(|j| j.name.as_str())
                    )
                )
            });
        }
    };
    if joint.kind == JointKind::Floating {
        return Err(format!(
            "joint '{}' is floating; drives take 1-dof joints",
            joint.name
        ));
    }
    let need = |key: &str, value: Option<f64>| -> Result<f64, String> {
        let value = value.ok_or_else(|| format!("profile '{}' needs `{key}`", section.profile))?;
        if value.is_finite() {
            Ok(value)
        } else {
            Err(format!("`{key}` must be finite"))
        }
    };
    let profile = match section.profile.as_str() {
        "constant" => Profile::Constant {
            value: need("value", section.value)?,
        },
        "ramp" => Profile::Ramp {
            value: need("value", section.value)?,
            rate: need("rate", section.rate)?,
        },
        "sine" => Profile::Sine {
            offset: need("offset", section.offset.or(Some(0.0)))?,
            amplitude: need("amplitude", section.amplitude)?,
            frequency: need("frequency", section.frequency)?,
            phase: need("phase", section.phase.or(Some(0.0)))?,
        },
        "spline" => {
            Profile::Spline(Spline::new(section.points.as_deref().ok_or_else(
                || "profile 'spline' needs `points = [[t, q], …]`".to_string(),
            )?)?)
        }
        other => {
            return Err(format!(
                "unknown profile '{other}'{}; profiles: constant, ramp, sine, spline",
                closest_suggestion(other, ["constant", "ramp", "sine", "spline"])
            ))
        }
    };
    Ok(Drive {
        name,
        q_index: joint.q_index,
        v_index: joint.v_index,
        profile,
    })
}

fn unit(vector: Option<[f64; 3]>, key: &str, loop_type: &str) -> Result<Vec3, String> {
    let v = Vec3::from(vector.ok_or_else(|| format!("type '{loop_type}' needs `{key}`"))?);
    let norm = v.norm();
    if !norm.is_finite() || norm < DIRECTION_TOLERANCE {
        return Err(format!("`{key}` must be a finite non-zero vector"));
    }
    Ok(v / norm)
}

/// A unit vector orthogonal to `n`: `preferred` projected off `n`, or `fallback` if that vanishes.
fn orthogonal(n: &Vec3, preferred: Vec3, fallback: Vec3) -> Vec3 {
    let projected = preferred - n * n.dot(&preferred);
    if projected.norm() > DIRECTION_TOLERANCE {
        projected.normalize()
    } else {
        (fallback - n * n.dot(&fallback)).normalize()
    }
}

fn resolve_loop(section: &LoopSection, model: &Model) -> Result<LoopClosure, String> {
    let find = |name: &str, role: &str| {
        model.description.link_index(name).ok_or_else(|| {
            format!(
                "unknown {role} link '{name}'{}",
                closest_suggestion(
                    name,
                    model.description.links.iter().map(|l| l.name.as_str())
                )
            )
        })
    };
    let parent = if section.parent == "world" && model.description.link_index("world").is_none() {
        None
    } else {
        Some(find(&section.parent, "parent")?)
    };
    let child = find(&section.child, "child")?;
    if parent.is_some_and(|p| model.links[p].body == model.links[child].body) {
        return Err(format!(
            "links '{}' and '{}' belong to the same rigid body; a loop must connect two bodies",
            section.parent, section.child
        ));
    }
    if parent.is_none() && model.links[child].body.is_none() {
        return Err(format!(
            "link '{}' is fixed to the world; a loop must close on a moving link",
            section.child
        ));
    }
    let points = section
        .point_in_parent
        .iter()
        .chain(&section.point_in_child);
    if points.into_iter().any(|x| !x.is_finite()) {
        return Err("points must be finite".to_string());
    }
    let kind = LoopKind::parse(&section.loop_type).ok_or_else(|| {
        format!(
            "unknown type '{}'{}; types: ball, planar_pin, planar_slider, slider",
            section.loop_type,
            closest_suggestion(
                &section.loop_type,
                ["ball", "planar_pin", "planar_slider", "slider"]
            )
        )
    })?;
    let t = section.loop_type.as_str();
    let directions = match kind {
        LoopKind::Ball => vec![Vec3::x(), Vec3::y(), Vec3::z()],
        LoopKind::PlanarPin => {
            let n = unit(section.normal, "normal", t)?;
            let e1 = orthogonal(&n, Vec3::x(), Vec3::y());
            vec![e1, n.cross(&e1)]
        }
        LoopKind::PlanarSlider => {
            let n = unit(section.normal, "normal", t)?;
            let axis = unit(section.axis, "axis", t)?;
            let e = n.cross(&axis);
            if e.norm() < DIRECTION_TOLERANCE {
                return Err(
                    "`axis` is parallel to `normal`; the slider must move within the plane"
                        .to_string(),
                );
            }
            vec![e.normalize()]
        }
        LoopKind::Slider => {
            let axis = unit(section.axis, "axis", t)?;
            let e1 = {
                let c = axis.cross(&Vec3::z());
                if c.norm() > DIRECTION_TOLERANCE {
                    c
                } else {
                    axis.cross(&Vec3::x())
                }
            }
            .normalize();
            vec![e1, axis.cross(&e1).normalize()]
        }
    };
    Ok(LoopClosure {
        name: section.name.clone(),
        kind,
        parent,
        point_in_parent: Vec3::from(section.point_in_parent),
        child,
        point_in_child: Vec3::from(section.point_in_child),
        directions,
    })
}
