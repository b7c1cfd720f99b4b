//! What the viewers are told about a log (docs/mcap.md §3–§5): how outputs are grouped into
//! tabs, the fixed colours of the lower / nominal / upper series, the part of space the robot moves
//! in (for a camera that frames it), and the Foxglove layout built from them ([`foxglove_layout`]).
//!
//! The rerun blueprint is built from the same facts by `scripts/viewers/rerun_blueprint.py` (the
//! rerun SDK writes `.rbl` files; its Rust crate needs a newer rustc than ours): the facts travel in
//! the MCAP itself, as channel metadata (`output`, `unit`, `group`) and entries of the `ribbon`
//! metadata record ([`SceneExtent::metadata`]).

mod foxglove_layout;

pub use foxglove_layout::{
    foxglove_layout, untrusted_title, untrusted_title_words, LayoutOutput, LayoutSensitivity,
    LayoutUntrusted, FOXGLOVE_LAYOUT_NAME, SENSITIVITY_COLOURS,
};

use std::collections::BTreeMap;

/// The series of an envelope channel with their fixed colours (`#rrggbb`), in `position` order:
/// lower blue, nominal bluish green, upper vermillion — three colours of the Okabe–Ito palette,
/// told apart with the common colour-vision deficiencies and visible on the dark backgrounds of
/// rerun and Foxglove as on the light one of the reports (a near-black nominal vanished in rerun).
pub const SERIES_COLOURS: [(&str, &str); 3] = [
    ("lower", "#0072b2"),
    ("nominal", "#009e73"),
    ("upper", "#d55e00"),
];

/// The series of a channel of the hull of true runs (an untrusted output's, docs/mcap.md §4),
/// in `position` order, with their labels and colour: both reddish purple, the Okabe–Ito colour
/// the envelope series do not use that reads on the viewers' dark backgrounds and on light ones
/// (its dots, not its colour, tell it from the envelope; the sensitivity plots that also use it
/// are in other tabs).
pub const RUNS_HULL_SERIES: [(&str, &str); 2] = [
    ("true runs, lowest", "#cc79a7"),
    ("true runs, highest", "#cc79a7"),
];

/// Smallest scene radius used for a camera, m: a robot whose links all sit at one point (a single
/// link) still gets a camera at a finite, non-zero distance.
pub const MIN_SCENE_RADIUS_M: f64 = 0.05;

/// The tab an output is shown in: one per quantity (joint positions, velocities, accelerations,
/// drive efforts, constraint forces) and one per recorded frame.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct ViewGroup {
    /// Sort key: tabs appear in this order (positions, frames, velocities, …).
    pub order: u8,
    /// Human title, e.g. `joint positions` or `frame tool0`.
    pub title: String,
}

/// The group of an output from the parts of its name (`["q", "elbow_joint"]`,
/// `["frame", "tool0", "z"]`, `["effort", "crank_drive"]`, `["lambda", "loop", "0"]`, …).
pub fn view_group(parts: &[String]) -> ViewGroup {
    let head = parts.first().map_or("", String::as_str);
    let (order, title) = match head {
        "q" => (0, "joint positions".to_string()),
        "frame" if parts.len() >= 3 => {
            (1, format!("frame {}", parts[1..parts.len() - 1].join(".")))
        }
        "v" => (3, "joint velocities".to_string()),
        "qdd" => (4, "joint accelerations".to_string()),
        "effort" => (5, "drive efforts".to_string()),
        "lambda" => (6, "constraint forces".to_string()),
        other => (7, other.to_string()),
    };
    ViewGroup { order, title }
}

/// Axis-aligned box of the link origins written to `/tf`, in the world frame, m. Starts empty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneExtent {
    /// Smallest x, y, z seen (`+∞` while empty).
    pub min: [f64; 3],
    /// Largest x, y, z seen (`−∞` while empty).
    pub max: [f64; 3],
}

impl Default for SceneExtent {
    fn default() -> Self {
        Self {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
        }
    }
}

impl SceneExtent {
    /// Grows the box to hold `point` (m, world frame); a non-finite point is ignored.
    pub fn include(&mut self, point: [f64; 3]) {
        if point.iter().all(|c| c.is_finite()) {
            for (axis, value) in point.into_iter().enumerate() {
                self.min[axis] = self.min[axis].min(value);
                self.max[axis] = self.max[axis].max(value);
            }
        }
    }

    /// Whether no point was included.
    pub fn is_empty(&self) -> bool {
        self.min[0] > self.max[0]
    }

    /// Centre of the box, m (the origin while empty).
    pub fn centre(&self) -> [f64; 3] {
        if self.is_empty() {
            return [0.0; 3];
        }
        std::array::from_fn(|axis| 0.5 * (self.min[axis] + self.max[axis]))
    }

    /// Half the box diagonal, m, at least [`MIN_SCENE_RADIUS_M`].
    pub fn radius(&self) -> f64 {
        if self.is_empty() {
            return MIN_SCENE_RADIUS_M;
        }
        let half_diagonal = (0..3)
            .map(|axis| (0.5 * (self.max[axis] - self.min[axis])).powi(2))
            .sum::<f64>()
            .sqrt();
        half_diagonal.max(MIN_SCENE_RADIUS_M)
    }

    /// Entries for the `ribbon` metadata record: `scene_centre_m` (`[x, y, z]` as JSON, m) and
    /// `scene_radius_m` (m), what a viewer script needs to place a camera.
    pub fn metadata(&self) -> BTreeMap<String, String> {
        let [x, y, z] = self.centre();
        BTreeMap::from([
            ("scene_centre_m".to_string(), format!("[{x}, {y}, {z}]")),
            ("scene_radius_m".to_string(), self.radius().to_string()),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn owned(parts: &[&str]) -> Vec<String> {
        parts.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn groups_follow_the_quantity_and_the_frame_name() {
        assert_eq!(
            view_group(&owned(&["q", "elbow_joint"])).title,
            "joint positions"
        );
        assert_eq!(
            view_group(&owned(&["frame", "tool0", "z"])).title,
            "frame tool0"
        );
        assert_eq!(
            view_group(&owned(&["frame", "tool.0", "x"])).title,
            "frame tool.0"
        );
        assert_eq!(
            view_group(&owned(&["lambda", "loop", "0"])).title,
            "constraint forces"
        );
        assert!(view_group(&owned(&["q", "a"])) < view_group(&owned(&["frame", "b", "x"])));
        assert!(view_group(&owned(&["v", "a"])) < view_group(&owned(&["effort", "d"])));
    }

    #[test]
    fn extent_frames_the_points() {
        let mut extent = SceneExtent::default();
        assert!(extent.is_empty());
        assert_eq!(extent.radius(), MIN_SCENE_RADIUS_M);
        extent.include([0.0, 0.0, 0.0]);
        extent.include([2.0, 0.0, 0.0]);
        extent.include([f64::NAN, 5.0, 5.0]);
        assert_eq!(extent.centre(), [1.0, 0.0, 0.0]);
        assert!((extent.radius() - 1.0).abs() < 1e-15);
        assert_eq!(extent.metadata()["scene_radius_m"], "1");
    }
}
