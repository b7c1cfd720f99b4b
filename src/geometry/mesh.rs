//! Collision meshes (docs/contacts.md §1, "Meshes"): a URDF `<mesh filename scale>` is found on
//! disk, read with `mesh-loader` (STL, OBJ, COLLADA), scaled, and replaced by the convex hull of
//! its vertices. Loaded once, when a scene declares contacts for the link; never otherwise.

use super::query::ConvexHull;
use crate::spatial::Vec3;
use std::path::{Path, PathBuf};

/// Relative amount by which a mesh's enclosed volume may fall short of its hull's before the hull
/// is reported as an over-approximation of a concave mesh. Vertices arrive as `f32` (mesh-loader),
/// so the two volumes of a convex mesh agree to about 1e-7 relative; 1e-6 leaves a factor of ten.
pub const CONCAVITY_NOTE_RELATIVE: f64 = 1e-6;

/// Why a collision mesh could not become a shape (the caller adds the URDF, link and index).
#[derive(Debug, PartialEq)]
pub(super) struct MeshProblem {
    /// The path the file name resolved to (or the file name, when it did not resolve).
    pub path: String,
    /// What is wrong and what to do.
    pub reason: String,
}

/// A loaded collision mesh: its hull and, for a concave mesh, a note saying the hull is larger.
pub(super) struct LoadedMesh {
    /// The hull of the scaled vertices, in the collision frame.
    pub hull: ConvexHull,
    /// The resolved path.
    pub path: String,
    /// `Some((hull volume, mesh volume))` (m³) when the mesh encloses less than its hull.
    pub concave: Option<(f64, f64)>,
}

/// Where `filename` (as written in the URDF at `urdf_path`) is on disk: `file://` and absolute
/// paths as they are, relative ones against the URDF's directory; `package://PKG/REST` as
/// `REST` inside the directory of package `PKG` that [`crate::ros::find_package`] finds
/// (`ROS_PACKAGE_PATH`, `AMENT_PREFIX_PATH`, the URDF's ancestors and their `package.xml`;
/// docs/ros.md §2). A package that is not found leaves the URI as it is (and loading it reports
/// it missing).
pub fn resolve_mesh_path(urdf_path: &str, filename: &str) -> PathBuf {
    let urdf_dir = Path::new(urdf_path)
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    if let Some(rest) = filename.strip_prefix("package://") {
        let (package, inside) = rest.split_once('/').unwrap_or((rest, ""));
        return crate::ros::find_package(package, Path::new(urdf_path))
            .map_or_else(|| PathBuf::from(filename), |dir| dir.join(inside));
    }
    let plain = filename.strip_prefix("file://").unwrap_or(filename);
    let path = Path::new(plain);
    if path.is_absolute() {
        path.to_path_buf()
    } else {
        urdf_dir.join(path)
    }
}

/// Reads the mesh `filename` of the URDF at `urdf_path`, scales its vertices by `scale` and builds
/// their convex hull.
pub(super) fn load_mesh(
    urdf_path: &str,
    filename: &str,
    scale: [f64; 3],
) -> Result<LoadedMesh, MeshProblem> {
    let resolved = resolve_mesh_path(urdf_path, filename);
    let path = resolved.display().to_string();
    let problem = |reason: String| MeshProblem {
        path: path.clone(),
        reason,
    };
    if filename.is_empty() {
        return Err(problem(
            "<mesh> has no filename; give the file's path (relative to the URDF, absolute or package://)".to_string(),
        ));
    }
    if !scale.iter().all(|s| s.is_finite() && *s != 0.0) {
        return Err(problem(format!(
            "scale {scale:?} must be three finite, non-zero numbers"
        )));
    }
    let bytes = std::fs::read(&resolved).map_err(|e| {
        problem(format!(
            "cannot read the file ({e}); check the path (relative names are resolved against the URDF's directory; package://PKG/… inside package PKG: {})", crate::ros::package_search_note()
        ))
    })?;
    let scene = mesh_loader::Loader::default()
        .load_from_slice(&bytes, &resolved)
        .map_err(|e| {
            if e.kind() == std::io::ErrorKind::Unsupported {
                // (mesh-loader's own message does not name the file; ours does.)
                problem(
                    "unsupported mesh format (neither its extension nor its content is STL, OBJ or COLLADA); convert it to STL, OBJ or COLLADA (.dae), or give the link a primitive <collision>".to_string(),
                )
            } else {
                problem(format!("the mesh cannot be parsed: {e}"))
            }
        })?;
    let scaled = |v: [f32; 3]| {
        Vec3::new(
            scale[0] * f64::from(v[0]),
            scale[1] * f64::from(v[1]),
            scale[2] * f64::from(v[2]),
        )
    };
    let points: Vec<Vec3> = scene
        .meshes
        .iter()
        .flat_map(|m| m.vertices.iter().map(|v| scaled(*v)))
        .collect();
    if points.is_empty() {
        return Err(problem(
            "the mesh has no vertices; export it again or give the link a primitive <collision>"
                .to_string(),
        ));
    }
    if points.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
        return Err(problem(
            "a vertex has a coordinate that is not a finite number".to_string(),
        ));
    }
    let hull = ConvexHull::of_points(&points).ok_or_else(|| {
        problem(format!(
            "the {} vertices span no volume (all on one plane, line or point): no convex hull; give the link a primitive <collision> (e.g. a thin <box>)",
            points.len()
        ))
    })?;
    // Volume the triangles enclose (divergence theorem; meaningful for a closed mesh).
    let mut six_volume = 0.0;
    for mesh in &scene.meshes {
        for face in &mesh.faces {
            let corner = |k: usize| mesh.vertices.get(face[k] as usize).map(|v| scaled(*v));
            if let (Some(a), Some(b), Some(c)) = (corner(0), corner(1), corner(2)) {
                six_volume += a.dot(&b.cross(&c));
            }
        }
    }
    let mesh_volume = (six_volume / 6.0).abs();
    let concave = (mesh_volume < hull.volume() * (1.0 - CONCAVITY_NOTE_RELATIVE))
        .then_some((hull.volume(), mesh_volume));
    Ok(LoadedMesh {
        hull,
        path,
        concave,
    })
}
