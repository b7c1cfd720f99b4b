//! A Foxglove layout (the JSON that *Layouts → Import from file…* reads) for a ribbon log
//! (docs/mcap.md §4): the nominal robot in a 3D panel on the left, and on the right one tab per
//! [`ViewGroup`](super::ViewGroup), each holding one Plot panel per output with the series
//! lower / nominal / upper in the fixed [`SERIES_COLOURS`](super::SERIES_COLOURS) and the
//! output's name and unit as the panel title; an output the a-posteriori check did not trust says
//! so in its title and shows its true runs as dots beside the envelope ([`untrusted_title`]).
//! Lichtblick, the open-source continuation of
//! Foxglove Studio, reads the same layout but takes panel titles from its own key, so both keys
//! are written (docs/mcap.md §8).

use super::{view_group, SceneExtent, RUNS_HULL_SERIES, SERIES_COLOURS};
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

/// Colours of the parameters in a sensitivity plot, in rank order: the Okabe–Ito colours that the
/// envelope series ([`SERIES_COLOURS`](super::SERIES_COLOURS)) do not use, so a sensitivity
/// series is never mistaken for a bound.
pub const SENSITIVITY_COLOURS: [&str; 4] = ["#e69f00", "#56b4e9", "#cc79a7", "#000000"];

/// The total Sobol' indices of one output to plot: its index topic and the parameters shown.
#[derive(Clone, Debug, PartialEq)]
pub struct LayoutSensitivity {
    /// The output's total-index topic (`/ribbon/sobol/total/frame/tool0/z`).
    pub topic: String,
    /// The parameters plotted, in rank order: (dimension index into the topic's `position`,
    /// parameter name); at most [`SENSITIVITY_COLOURS`]`.len()` of them.
    pub parameters: Vec<(usize, String)>,
}

/// How an output's plot says that the check did not trust its surrogate.
#[derive(Clone, Debug, PartialEq)]
pub struct LayoutUntrusted {
    /// The output's largest check misfit over its largest envelope width.
    pub relative_misfit: f64,
    /// The topic of its hull of true runs (`/ribbon/runs/q/j1`), when the log has it.
    pub runs_topic: Option<String>,
}

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
    /// Its total Sobol' indices, when the log has them and some parameter matters (a plot in the
    /// group's sensitivity tab).
    pub sensitivity: Option<LayoutSensitivity>,
    /// Whether the check did not trust it, and how its plot shows that; `None`: trusted or
    /// unchecked.
    pub untrusted: Option<LayoutUntrusted>,
}

/// The panel title of an output: `frame.tool0.z [m]`, or the name alone when unitless.
pub fn panel_title(name: &str, unit: &str) -> String {
    if unit.is_empty() {
        name.to_string()
    } else {
        format!("{name} [{unit}]")
    }
}

/// The panel title of an output the check did not trust: `⚠ q.j1 [rad] — NOT TRUSTED (misfit
/// 65.6 %): true runs dotted` (the misfit in % of the output's largest envelope width, as the
/// exit-4 message words it; the last part only when the plot shows the true runs). The sign
/// comes first because a viewer cuts a long title to the panel's width: in a grid of seven plots
/// rerun shows about twenty characters, the sign and the output's name. The rerun blueprint
/// (`scripts/viewers/rerun_blueprint.py`) writes the same.
pub fn untrusted_title(title: &str, relative_misfit: f64, shows_runs: bool) -> String {
    format!(
        "⚠ {}",
        untrusted_title_words(title, relative_misfit, shows_runs)
    )
}

/// [`untrusted_title`] without its leading sign: `q.j1 [rad] — NOT TRUSTED (misfit 65.6 %): true
/// runs dotted`. The report's band plots take this (their embedded font has no ⚠, and a report
/// plot's title is never cut).
pub fn untrusted_title_words(title: &str, relative_misfit: f64, shows_runs: bool) -> String {
    format!(
        "{title} — NOT TRUSTED (misfit {:.1} %){}",
        100.0 * relative_misfit,
        if shows_runs { ": true runs dotted" } else { "" }
    )
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

/// The Plot panel of one output: its envelope and, when the check did not trust it, the hull of
/// its true runs as dots (no line: the dots tell them from the envelope in any colour scheme).
fn plot_panel(output: &LayoutOutput) -> Value {
    let mut paths: Vec<Value> = SERIES_COLOURS
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
    let mut title = panel_title(&output.name, &output.unit);
    if let Some(untrusted) = &output.untrusted {
        if let Some(topic) = &untrusted.runs_topic {
            paths.extend(
                RUNS_HULL_SERIES
                    .iter()
                    .enumerate()
                    .map(|(index, (label, colour))| {
                        json!({
                            "value": message_path(topic, &format!("position[{index}]")),
                            "enabled": true,
                            "timestampMethod": "receiveTime",
                            "label": label,
                            "color": colour,
                            "lineSize": 1.0,
                            "showLine": false,
                        })
                    }),
            );
        }
        title = untrusted_title(
            &title,
            untrusted.relative_misfit,
            untrusted.runs_topic.is_some(),
        );
    }
    plot_config(&title, paths)
}

/// A Plot panel's configuration: `paths` against time, titled `title` (under both viewers' title
/// keys), the legend floating over the plot with the values at the playback time.
fn plot_config(title: &str, paths: Vec<Value>) -> Value {
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

/// The Plot panel of one output's total Sobol' indices: one series per plotted parameter,
/// labelled with its name, titled `NAME: total Sobol' index`.
fn sensitivity_panel(output: &LayoutOutput, sensitivity: &LayoutSensitivity) -> Value {
    let paths: Vec<Value> = sensitivity
        .parameters
        .iter()
        .zip(SENSITIVITY_COLOURS)
        .map(|((dimension, name), colour)| {
            json!({
                "value": message_path(&sensitivity.topic, &format!("position[{dimension}]")),
                "enabled": true,
                "timestampMethod": "receiveTime",
                "label": name,
                "color": colour,
                "lineSize": 1.0,
                "showLine": true,
            })
        })
        .collect();
    let mut config = plot_config(&format!("{}: total Sobol' index", output.name), paths);
    // An index lies in [0, 1]: a fixed axis keeps the plots of one tab comparable.
    config["minYValue"] = json!(0.0);
    config["maxYValue"] = json!(1.0);
    config
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

    // Per group: its envelope plots, and the sensitivity plots of those outputs that have one.
    let mut groups: Vec<(super::ViewGroup, Vec<String>, Vec<String>)> = Vec::new();
    for (index, output) in outputs.iter().enumerate() {
        let id = format!("Plot!ribbon{index}");
        config.insert(id.clone(), plot_panel(output));
        let sensitivity_id = output
            .sensitivity
            .as_ref()
            .filter(|s| !s.parameters.is_empty())
            .map(|sensitivity| {
                let id = format!("Plot!ribbon-sobol{index}");
                config.insert(id.clone(), sensitivity_panel(output, sensitivity));
                id
            });
        let group = view_group(&output.parts);
        let slot = match groups.iter().position(|(g, _, _)| *g == group) {
            Some(slot) => slot,
            None => {
                groups.push((group, Vec::new(), Vec::new()));
                groups.len() - 1
            }
        };
        groups[slot].1.push(id);
        groups[slot].2.extend(sensitivity_id);
    }
    groups.sort_by(|a, b| a.0.cmp(&b.0));
    let mut tabs: Vec<Value> = groups
        .iter()
        .map(|(group, ids, _)| {
            json!({
                "title": group.title,
                "layout": mosaic(ids, "column"),
            })
        })
        .collect();
    // The sensitivity tabs come after every envelope tab: the envelopes are the answer, the
    // indices say which parameter it depends on when (docs/sobol-indices.md).
    tabs.extend(
        groups
            .iter()
            .filter(|(_, _, sensitivity_ids)| !sensitivity_ids.is_empty())
            .map(|(group, _, sensitivity_ids)| {
                json!({
                    "title": format!("{} · sensitivity", group.title),
                    "layout": mosaic(sensitivity_ids, "column"),
                })
            }),
    );
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
            sensitivity: None,
            untrusted: None,
        }
    }

    #[test]
    fn an_untrusted_output_says_so_and_shows_its_true_runs_as_dots() {
        let mut elbow = output("q.elbow_joint", "rad");
        elbow.untrusted = Some(LayoutUntrusted {
            relative_misfit: 0.656,
            runs_topic: Some("/ribbon/runs/q/elbow_joint".to_string()),
        });
        let mut wrist = output("q.wrist_joint", "rad");
        wrist.untrusted = Some(LayoutUntrusted {
            relative_misfit: 0.08,
            runs_topic: None,
        });
        let layout = foxglove_layout(
            &[elbow, wrist, output("frame.tool0.z", "m")],
            &SceneExtent::default(),
        );
        let config = &layout["configById"];
        let elbow = &config["Plot!ribbon0"];
        let title = "⚠ q.elbow_joint [rad] — NOT TRUSTED (misfit 65.6 %): true runs dotted";
        assert_eq!(elbow["foxglovePanelTitle"], title);
        assert_eq!(elbow["lichtblickPanelTitle"], title);
        let paths = elbow["paths"].as_array().unwrap();
        assert_eq!(paths.len(), 5);
        assert_eq!(paths[3]["value"], "/ribbon/runs/q/elbow_joint.position[0]");
        assert_eq!(paths[4]["value"], "/ribbon/runs/q/elbow_joint.position[1]");
        assert_eq!(paths[4]["label"], RUNS_HULL_SERIES[1].0);
        assert_eq!(paths[3]["showLine"], false);
        for (_, envelope_colour) in SERIES_COLOURS {
            assert_ne!(paths[3]["color"], envelope_colour);
        }
        // Without the hull's channels: the title alone.
        let wrist = &config["Plot!ribbon1"];
        assert_eq!(
            wrist["foxglovePanelTitle"],
            "⚠ q.wrist_joint [rad] — NOT TRUSTED (misfit 8.0 %)"
        );
        assert_eq!(wrist["paths"].as_array().unwrap().len(), 3);
        // A trusted output's plot is unchanged.
        let tool = &config["Plot!ribbon2"];
        assert_eq!(tool["foxglovePanelTitle"], "frame.tool0.z [m]");
        assert_eq!(tool["paths"].as_array().unwrap().len(), 3);
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
    fn sensitivity_plots_go_to_a_tab_after_the_envelopes() {
        let mut elbow = output("q.elbow_joint", "rad");
        elbow.sensitivity = Some(LayoutSensitivity {
            topic: "/ribbon/sobol/total/q/elbow_joint".to_string(),
            parameters: vec![
                (2, "link.a.mass".to_string()),
                (0, "link.b.mass".to_string()),
            ],
        });
        let mut wrist = output("q.wrist_joint", "rad");
        // No parameter reached the floor: no plot.
        wrist.sensitivity = Some(LayoutSensitivity {
            topic: "/ribbon/sobol/total/q/wrist_joint".to_string(),
            parameters: Vec::new(),
        });
        let layout = foxglove_layout(
            &[elbow, wrist, output("frame.tool0.z", "m")],
            &SceneExtent::default(),
        );
        let config = layout["configById"].as_object().unwrap();
        let tabs = config["Tab!ribbon-outputs"]["tabs"].as_array().unwrap();
        let titles: Vec<&str> = tabs.iter().map(|t| t["title"].as_str().unwrap()).collect();
        assert_eq!(
            titles,
            [
                "joint positions",
                "frame tool0",
                "joint positions · sensitivity"
            ]
        );
        assert_eq!(tabs[2]["layout"], "Plot!ribbon-sobol0");
        assert!(!config.contains_key("Plot!ribbon-sobol1"));
        let plot = &config["Plot!ribbon-sobol0"];
        assert_eq!(
            plot["foxglovePanelTitle"],
            "q.elbow_joint: total Sobol' index"
        );
        assert_eq!(
            plot["paths"][0]["value"],
            "/ribbon/sobol/total/q/elbow_joint.position[2]"
        );
        assert_eq!(plot["paths"][0]["label"], "link.a.mass");
        assert_eq!(plot["paths"][1]["color"], SENSITIVITY_COLOURS[1]);
        for (_, envelope_colour) in SERIES_COLOURS {
            assert!(!SENSITIVITY_COLOURS.contains(&envelope_colour));
        }
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
