//! A Foxglove layout (the JSON that *Layouts → Import from file…* reads) for a ribbon log
//! (docs/mcap.md §4): the nominal robot in a 3D panel on the left, and on the right one tab per
//! [`ViewGroup`](super::ViewGroup), each holding one Plot panel per output with the series
//! lower / nominal / upper in the fixed [`SERIES_COLOURS`](super::SERIES_COLOURS) and the
//! output's name and unit as the panel title. Lichtblick, the open-source continuation of
//! Foxglove Studio, reads the same layout but takes panel titles from its own key, so both keys
//! are written (docs/mcap.md §8).

use super::{view_group, SceneExtent, SERIES_COLOURS};
use crate::output::mcap::{ROBOT_DESCRIPTION_TOPIC, WORLD_FRAME};
use serde_json::{json, Map, Value};

/// File name of the layout: the MCAP attachment's name and the file in a report directory.
pub const FOXGLOVE_LAYOUT_NAME: &str = "foxglove-layout.json";

/// Camera elevation above the horizontal, degrees (Foxglove's `phi` is measured from the vertical
/// axis: 90° − this): low enough to see the arm's height, high enough to see its reach.
const CAMERA_ELEVATION_DEG: f64 = 30.0;
/// Camera azimuth from the world x axis, degrees: a three-quarter view.
const CAMERA_AZIMUTH_DEG: f64 = 45.0;
/// Camera distance in scene radii: with Foxglove's 45° vertical field of view a sphere of radius r
/// fills the view's height at 1/sin(22.5°) ≈ 2.6 r; 3.2 leaves a margin.
const CAMERA_DISTANCE_IN_RADII: f64 = 3.2;
/// Length of the frame axes drawn per link, in scene radii: visible, yet small beside the links.
const AXIS_LENGTH_IN_RADII: f64 = 0.12;
/// Share of the window's width given to the 3D panel, %.
const ROBOT_PANEL_PERCENT: f64 = 35.0;

/// One plotted output.
#[derive(Clone, Debug, PartialEq)]
pub struct LayoutOutput {
    /// The output's name (`frame.tool0.z`).
    pub name: String,
    /// Its name parts (for grouping).
    pub parts: Vec<String>,
    /// Its unit (`m`, `rad`, `N·m`, …; empty when unitless).
    pub unit: String,
    /// Its envelope topic (`/ribbon/envelope/frame/tool0/z`).
    pub topic: String,
}

/// The panel title of an output: `frame.tool0.z [m]`, or the name alone when unitless.
pub fn panel_title(name: &str, unit: &str) -> String {
    if unit.is_empty() {
        name.to_string()
    } else {
        format!("{name} [{unit}]")
    }
}

/// A Foxglove message path into a topic: quoted when the topic holds a character that ends a
/// topic name in Foxglove's syntax (a dot or a space).
fn message_path(topic: &str, field: &str) -> String {
    if topic.contains(['.', ' ', '"']) {
        format!("\"{}\".{field}", topic.replace('"', "\\\""))
    } else {
        format!("{topic}.{field}")
    }
}

/// A balanced mosaic tree over `ids` (Foxglove's layout tree: leaves are panel ids, nodes split
/// `first` / `second` in `direction` at `splitPercentage`).
fn mosaic(ids: &[String], direction: &str) -> Value {
    match ids {
        [] => Value::Null,
        [one] => Value::String(one.clone()),
        _ => {
            let half = ids.len() / 2;
            let other = if direction == "row" { "column" } else { "row" };
            // Alternating directions keep the panels near square; the split follows the counts.
            json!({
                "first": mosaic(&ids[..half], other),
                "second": mosaic(&ids[half..], other),
                "direction": direction,
                "splitPercentage": 100.0 * half as f64 / ids.len() as f64,
            })
        }
    }
}

/// The Plot panel of one output.
fn plot_panel(output: &LayoutOutput) -> Value {
    let paths: Vec<Value> = SERIES_COLOURS
        .iter()
        .enumerate()
        .map(|(index, (label, colour))| {
            json!({
                "value": message_path(&output.topic, &format!("position[{index}]")),
                "enabled": true,
                "timestampMethod": "receiveTime",
                "label": label,
                "color": colour,
                "lineSize": if *label == "nominal" { 1.5 } else { 1.0 },
                "showLine": true,
            })
        })
        .collect();
    let title = panel_title(&output.name, &output.unit);
    json!({
        "foxglovePanelTitle": title,
        "lichtblickPanelTitle": title,
        "title": title,
        "paths": paths,
        "showLegend": true,
        "legendDisplay": "floating",
        "showPlotValuesInLegend": true,
        "showXAxisLabels": true,
        "showYAxisLabels": true,
        "isSynced": true,
        "xAxisVal": "timestamp",
        "sidebarDimension": 240,
    })
}

/// The 3D panel: the URDF from `/robot_description` moved by `/tf`, a camera that frames
/// `extent`, small axes and no frame labels.
fn robot_panel(extent: &SceneExtent) -> Value {
    let radius = extent.radius();
    let [x, y, z] = extent.centre();
    json!({
        "foxglovePanelTitle": "nominal robot",
        "lichtblickPanelTitle": "nominal robot",
        "followTf": WORLD_FRAME,
        "followMode": "follow-none",
        "cameraState": {
            "perspective": true,
            "distance": CAMERA_DISTANCE_IN_RADII * radius,
            "phi": 90.0 - CAMERA_ELEVATION_DEG,
            "thetaOffset": CAMERA_AZIMUTH_DEG,
            "target": [0.0, 0.0, 0.0],
            "targetOffset": [x, y, z],
            "targetOrientation": [0.0, 0.0, 0.0, 1.0],
            "fovy": 45.0,
            "near": 0.001 * radius,
            "far": 1000.0 * radius,
        },
        "scene": {
            "enableStats": false,
            "transforms": {
                "enablePreloading": true,
                "showLabel": false,
                "axisScale": AXIS_LENGTH_IN_RADII * radius,
                "lineWidth": 1.0,
            },
        },
        "layers": {
            "ribbon-urdf": {
                "layerId": "foxglove.Urdf",
                "instanceId": "ribbon-urdf",
                "label": "URDF (/robot_description)",
                "visible": true,
                "frameLocked": true,
                "sourceType": "topic",
                "topic": ROBOT_DESCRIPTION_TOPIC,
                "url": "",
                "filePath": "",
                "parameter": "",
                "framePrefix": "",
                "displayMode": "visual",
                "fallbackColor": "#9aa5b1",
                "order": 1,
            },
            "ribbon-grid": {
                "layerId": "foxglove.Grid",
                "instanceId": "ribbon-grid",
                "label": "grid",
                "visible": true,
                "frameLocked": true,
                "frameId": WORLD_FRAME,
                "size": (4.0 * radius).max(0.1),
                "divisions": 10,
                "lineWidth": 1,
                "color": "#248eff55",
                "position": [x, y, 0.0],
                "rotation": [0, 0, 0],
                "order": 2,
            },
        },
        "topics": {
            ROBOT_DESCRIPTION_TOPIC: {"visible": true},
        },
    })
}

/// The layout of a log holding `outputs` whose robot moves inside `extent`. Panel ids are stable
/// (`Plot!ribbon<i>` in output order), so the same study always gives the same file.
pub fn foxglove_layout(outputs: &[LayoutOutput], extent: &SceneExtent) -> Value {
    let mut config = Map::new();
    config.insert("3D!ribbon-robot".to_string(), robot_panel(extent));

    let mut groups: Vec<(super::ViewGroup, Vec<String>)> = Vec::new();
    for (index, output) in outputs.iter().enumerate() {
        let id = format!("Plot!ribbon{index}");
        config.insert(id.clone(), plot_panel(output));
        let group = view_group(&output.parts);
        match groups.iter_mut().find(|(g, _)| *g == group) {
            Some((_, ids)) => ids.push(id),
            None => groups.push((group, vec![id])),
        }
    }
    groups.sort_by(|a, b| a.0.cmp(&b.0));
    let tabs: Vec<Value> = groups
        .iter()
        .map(|(group, ids)| {
            json!({
                "title": group.title,
                "layout": mosaic(ids, "column"),
            })
        })
        .collect();
    config.insert(
        "Tab!ribbon-outputs".to_string(),
        json!({"activeTabIdx": 0, "tabs": tabs}),
    );
    json!({
        "configById": config,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": {
            "first": "3D!ribbon-robot",
            "second": "Tab!ribbon-outputs",
            "direction": "row",
            "splitPercentage": ROBOT_PANEL_PERCENT,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn output(name: &str, unit: &str) -> LayoutOutput {
        let parts: Vec<String> = name.split('.').map(str::to_string).collect();
        LayoutOutput {
            name: name.to_string(),
            topic: format!("/ribbon/envelope/{}", parts.join("/")),
            parts,
            unit: unit.to_string(),
        }
    }

    #[test]
    fn one_plot_per_output_grouped_in_tabs_with_units_and_colours() {
        let outputs = [
            output("frame.tool0.z", "m"),
            output("q.elbow_joint", "rad"),
            output("q.wrist_joint", "rad"),
            output("effort.drive", "N·m"),
        ];
        let mut extent = SceneExtent::default();
        extent.include([0.0, 0.0, 0.0]);
        extent.include([0.0, 0.0, 1.0]);
        let layout = foxglove_layout(&outputs, &extent);
        let config = layout["configById"].as_object().unwrap();
        let plots: Vec<&Value> = config
            .iter()
            .filter(|(id, _)| id.starts_with("Plot!"))
            .map(|(_, v)| v)
            .collect();
        assert_eq!(plots.len(), 4);
        let tool = &config["Plot!ribbon0"];
        assert_eq!(tool["foxglovePanelTitle"], "frame.tool0.z [m]");
        // Lichtblick (the open-source Foxglove Studio) reads its own title key.
        assert_eq!(tool["lichtblickPanelTitle"], "frame.tool0.z [m]");
        assert_eq!(
            tool["paths"][2]["value"],
            "/ribbon/envelope/frame/tool0/z.position[2]"
        );
        assert_eq!(tool["paths"][2]["label"], "upper");
        assert_eq!(tool["paths"][0]["color"], SERIES_COLOURS[0].1);
        let tabs = config["Tab!ribbon-outputs"]["tabs"].as_array().unwrap();
        let titles: Vec<&str> = tabs.iter().map(|t| t["title"].as_str().unwrap()).collect();
        assert_eq!(titles, ["joint positions", "frame tool0", "drive efforts"]);
        assert_eq!(
            tabs[0]["layout"],
            json!({"first": "Plot!ribbon1", "second": "Plot!ribbon2", "direction": "column", "splitPercentage": 50.0})
        );
        let robot = &config["3D!ribbon-robot"];
        assert_eq!(robot["lichtblickPanelTitle"], robot["foxglovePanelTitle"]);
        assert_eq!(robot["scene"]["transforms"]["enablePreloading"], true);
        let camera = &robot["cameraState"];
        assert_eq!(camera["targetOffset"], json!([0.0, 0.0, 0.5]));
        assert!((camera["distance"].as_f64().unwrap() - 1.6).abs() < 1e-12);
    }

    #[test]
    fn topics_with_dots_are_quoted() {
        assert_eq!(message_path("/a.b", "position[0]"), "\"/a.b\".position[0]");
        assert_eq!(message_path("/a/b", "position[0]"), "/a/b.position[0]");
    }

    #[test]
    fn mosaic_holds_every_panel_once() {
        let ids: Vec<String> = (0..5).map(|i| format!("P{i}")).collect();
        let text = mosaic(&ids, "column").to_string();
        for id in &ids {
            assert_eq!(text.matches(&format!("\"{id}\"")).count(), 1, "{text}");
        }
    }
}
