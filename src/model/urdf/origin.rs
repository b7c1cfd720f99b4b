//! `<origin>` of a joint or of an `<inertial>`: the position `xyz` and the orientation, written
//! as `rpy` or — from URDF 1.1 on — as the quaternion `quat_xyzw`, which is turned into roll,
//! pitch, yaw here so that a [`Description`](crate::model::Description) holds one form.
//!
//! **Quaternion to roll, pitch, yaw.** URDF's rpy is `R = Rz(yaw) · Ry(pitch) · Rx(roll)`, so
//! `R₂₀ = −sin pitch`, `(R₂₁, R₂₂) = cos pitch · (sin roll, cos roll)` and
//! `(R₁₀, R₀₀) = cos pitch · (sin yaw, cos yaw)`. The quaternion `(x, y, z, w)` is normalised
//! first (as urdfdom does), then the five entries are written from it
//! (`R₀₀ = 1 − 2(y² + z²)`, `R₁₀ = 2(xy + wz)`, `R₂₀ = 2(xz − wy)`, `R₂₁ = 2(yz + wx)`,
//! `R₂₂ = 1 − 2(x² + y²)`), and `pitch = atan2(−R₂₀, hypot(R₀₀, R₁₀))` (accurate at every angle,
//! unlike `asin`), `roll = atan2(R₂₁, R₂₂)`, `yaw = atan2(R₁₀, R₀₀)`. At `cos pitch = 0`
//! (gimbal lock) only `yaw ∓ roll` is defined: roll is set to 0 and yaw read from
//! `(R₀₁, R₁₁) = (−sin yaw, cos yaw)`, which reproduces the whole matrix.

use super::version::UrdfVersion;
use super::xml::Reader;
use crate::model::error::ModelError;
use crate::spatial::quaternion::normalized_xyzw;
use roxmltree::Node;

/// Below this `cos pitch` a quaternion is treated as gimbal-locked (roll set to 0). Away from the
/// lock, roll and yaw carry a rounding error of about `ε / cos pitch` (ε = 2.2e-16, the entries'
/// error); at the lock, setting roll to 0 errs by `cos pitch` in the matrix. The two balance
/// at `cos pitch ≈ √ε ≈ 1.5e-8`, so the rotation rebuilt from rpy differs from the quaternion's by
/// at most about 1.5e-8, and by about 1e-16 for orientations away from pitch = ±90°.
const GIMBAL_LOCK_COS_PITCH: f64 = 1.5e-8;

/// Reads an `<origin>` element: `(xyz, rpy)`, both zero when absent. `owner` is `link 'a'` or
/// `joint 'j'`; `xyz_field` and `rpy_field` name the values in errors (`"<origin>"`,
/// `"<origin rpy>"`).
///
/// `quat_xyzw` (four numbers, normalised) gives the orientation in URDF 1.1 and later; with `rpy`
/// as well it is an error (urdfdom refuses it too), as is a quaternion of zero length (urdfdom
/// reads it as no rotation; ribbon does not guess). In a version-1.0 file `quat_xyzw` is ignored
/// with a note, as urdfdom ignores it.
pub(super) fn read_origin<'input>(
    reader: &mut Reader<'_, 'input>,
    node: Node<'_, 'input>,
    owner: &str,
    xyz_field: &str,
    rpy_field: &str,
) -> Result<([f64; 3], [f64; 3]), ModelError> {
    let xyz = reader
        .vector3(node, owner, "xyz", xyz_field)?
        .unwrap_or_default();
    let rpy = reader.vector3(node, owner, "rpy", rpy_field)?;
    let Some(text) = node.attribute("quat_xyzw") else {
        return Ok((xyz, rpy.unwrap_or_default()));
    };
    if reader.version < UrdfVersion::V1_1 {
        let line = reader.line(node);
        reader.note(
            line,
            format!("{owner} <{} quat_xyzw=\"{text}\">: quat_xyzw is URDF 1.1 and this file is version 1.0 (a file without <robot version> is 1.0); ignored, as Pinocchio ignores it — write version=\"1.1\" in <robot> if this orientation is meant", node.tag_name().name()),
        );
        return Ok((xyz, rpy.unwrap_or_default()));
    }
    if rpy.is_some() {
        return Err(reader.bad_number(
            node,
            owner,
            "quat_xyzw",
            text,
            "allowed together with rpy: give the orientation once, as rpy or as quat_xyzw (Pinocchio refuses both too)",
        ));
    }
    let quat_field = rpy_field.replace("rpy", "quat_xyzw");
    let quaternion = reader
        .vector::<4>(
            node,
            owner,
            "quat_xyzw",
            &quat_field,
            "four numbers x y z w separated by spaces",
        )?
        .unwrap_or([0.0, 0.0, 0.0, 1.0]);
    let rpy = rpy_from_quaternion(quaternion).ok_or_else(|| {
        reader.bad_number(
            node,
            owner,
            "quat_xyzw",
            text,
            "a rotation: a quaternion of zero length has no orientation",
        )
    })?;
    Ok((xyz, rpy))
}

/// Roll, pitch, yaw (rad) of the rotation of the quaternion `[x, y, z, w]` (any non-zero length;
/// normalised here), by the formulas of the module documentation; `None` for a quaternion of zero
/// or non-finite length.
pub(super) fn rpy_from_quaternion(quaternion: [f64; 4]) -> Option<[f64; 3]> {
    let [x, y, z, w] = normalized_xyzw(quaternion)?;
    let r00 = 1.0 - 2.0 * (y * y + z * z);
    let r10 = 2.0 * (x * y + w * z);
    let minus_r20 = 2.0 * (w * y - x * z);
    let cos_pitch = r00.hypot(r10);
    let pitch = minus_r20.atan2(cos_pitch);
    if cos_pitch > GIMBAL_LOCK_COS_PITCH {
        let r21 = 2.0 * (y * z + w * x);
        let r22 = 1.0 - 2.0 * (x * x + y * y);
        Some([r21.atan2(r22), pitch, r10.atan2(r00)])
    } else {
        let r01 = 2.0 * (x * y - w * z);
        let r11 = 1.0 - 2.0 * (x * x + z * z);
        Some([0.0, pitch, (-r01).atan2(r11)])
    }
}
