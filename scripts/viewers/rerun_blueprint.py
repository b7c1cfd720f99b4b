#!/usr/bin/env python3
"""Writes a rerun blueprint (.rbl) for a ribbon MCAP log (docs/mcap.md §5).

Usage: rerun_blueprint.py LOG.mcap OUT.rbl [--manifest OUT.json] [--active-tab GROUP]

Reads the log's envelope channels (metadata `output`, `unit`, `group`) and the `ribbon` metadata
record (`robot`: rerun's entity root for the URDF geometry; `scene_centre_m`, `scene_radius_m`: the
box the robot moves in), and writes a blueprint with:
- left, a 3D view of the nominal robot (URDF visual geometry moved by /tf), the eye placed like the
  Foxglove layout's camera (3.2 scene radii from the centre, 30° up, 45° azimuth);
- right, one tab per group, one time-series view per output titled `name [unit]`, holding only the
  output's `/ribbon/envelope/…/position` entity, series lower / nominal / upper in the layout's
  fixed colours; then, when the log has Sobol' indices, one tab `GROUP · sensitivity` per group
  with a view per output of its total indices (`/ribbon/sobol/total/…/position`), showing the
  parameters whose index ever reaches SENSITIVITY_PLOT_FLOOR (at most four, largest peak first:
  the Foxglove layout's rule and colours, src/output/envelope_log.rs);
- for a study the a-posteriori check did not trust (the `ribbon` record's `check` entry), each
  untrusted output's view titled `⚠ name [unit] — NOT TRUSTED (misfit X %): true runs dotted` and
  holding, beside the envelope, the hull of its true runs (`/ribbon/runs/…/position`) as dots;
- the time panel on `message_log_time` (seconds from 0 when converted with --timeline-type duration).

View it with the log converted under the same application id:
    rerun mcap convert --timeline-type duration --application-id ribbon LOG.mcap -o LOG.rrd
    rerun LOG.rrd OUT.rbl
--manifest writes the entity paths the blueprint shows, for checks (tests/viewers.rs);
--active-tab opens the tab of that group (e.g. "frame tool0") instead of the first.
Needs rerun-sdk 0.41 and mcap (the reference venv: target/reference-venv/bin/python).
"""

import argparse
import json
import math
import sys

import rerun as rr
import rerun.blueprint as rrb
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

APPLICATION_ID = "ribbon"
ENVELOPE_PREFIX = "/ribbon/envelope/"
RUNS_PREFIX = "/ribbon/runs/"
SOBOL_TOTAL_PREFIX = "/ribbon/sobol/total/"
# Must match src/output/envelope_log.rs SENSITIVITY_PLOT_FLOOR and foxglove_layout.rs
# SENSITIVITY_COLOURS: the parameters a sensitivity view shows, and their colours in rank order.
SENSITIVITY_PLOT_FLOOR = 0.01
SENSITIVITY_COLOURS = ["#e69f00", "#56b4e9", "#cc79a7", "#000000"]
HIDDEN_SERIES_COLOUR = "#9aa5b1"
TIMELINE = "message_log_time"
# Must match src/output/viewer/mod.rs SERIES_COLOURS and foxglove_layout.rs's camera constants.
SERIES = [("lower", "#0072b2", 1.5), ("nominal", "#009e73", 2.5), ("upper", "#d55e00", 1.5)]
# Must match src/output/viewer/mod.rs RUNS_HULL_SERIES: the true runs' hull, drawn as dots.
RUNS_SERIES = [("true runs, lowest", "#cc79a7"), ("true runs, highest", "#cc79a7")]
RUNS_MARKER_SIZE = 1.5
CAMERA_ELEVATION_DEG = 30.0
CAMERA_AZIMUTH_DEG = 45.0
CAMERA_DISTANCE_IN_RADII = 3.2
GROUP_ORDER = [
    "joint positions",
    "frame ",
    "joint velocities",
    "joint accelerations",
    "drive efforts",
    "constraint forces",
]


def group_rank(title):
    for rank, prefix in enumerate(GROUP_ORDER):
        if title == prefix or (prefix.endswith(" ") and title.startswith(prefix)):
            return rank
    return len(GROUP_ORDER)


def rgba(hex_colour):
    value = int(hex_colour.lstrip("#"), 16)
    return [(value >> 16) & 255, (value >> 8) & 255, value & 255, 255]


def read_sensitivities(path, channels):
    """Per total-index channel: (output, group, topic, [(dimension index, name)] shown, all
    dimension names), the shown ones ranked by their largest index over the record times."""
    peaks, names = {}, {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, _, message in reader.iter_decoded_messages(topics=[c.topic for c in channels]):
            names.setdefault(channel.topic, list(message.name))
            old = peaks.get(channel.topic, [0.0] * len(message.position))
            peaks[channel.topic] = [max(a, b) for a, b in zip(old, message.position)]
    result = []
    for c in channels:
        peak = peaks.get(c.topic, [])
        ranked = sorted((j for j in range(len(peak)) if peak[j] >= SENSITIVITY_PLOT_FLOOR), key=lambda j: (-peak[j], j))
        shown = [(j, names[c.topic][j]) for j in ranked[: len(SENSITIVITY_COLOURS)]]
        if shown:
            result.append((c.metadata["output"], c.metadata.get("group", "outputs"), c.topic, shown, names[c.topic]))
    return result


def read_log(path):
    """(outputs [(name, unit, group, topic, untrusted)], robot name, scene centre, scene radius,
    sensitivities (read_sensitivities)); `untrusted` is None for an output the check trusted (or
    a log without a verdict), else (relative misfit, the topic of its true runs' hull or None)."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        if summary is None:
            sys.exit(f"{path}: no summary section; is it a complete ribbon log?")
        outputs = [
            (c.metadata["output"], c.metadata.get("unit", ""), c.metadata.get("group", "outputs"), c.topic)
            for c in sorted(summary.channels.values(), key=lambda c: c.id)
            if c.topic.startswith(ENVELOPE_PREFIX) and "output" in c.metadata
        ]
        runs_topics = {
            c.metadata["output"]: c.topic
            for c in summary.channels.values()
            if c.topic.startswith(RUNS_PREFIX) and "output" in c.metadata
        }
        totals = [
            c
            for c in sorted(summary.channels.values(), key=lambda c: c.id)
            if c.topic.startswith(SOBOL_TOTAL_PREFIX) and "output" in c.metadata
        ]
        records = {m.name: m.metadata for m in reader.iter_metadata()}
    if not outputs:
        sys.exit(f"{path}: no envelope channels with `output` metadata (written by ribbon ≥ this version)")
    robot = records.get("ribbon", {}).get("robot")
    if not robot:
        sys.exit(f"{path}: no `ribbon` metadata record naming the robot")
    viewer = records.get("ribbon", {})
    misfits = {
        entry["name"]: entry["relative_misfit"]
        for entry in json.loads(viewer.get("check", "{}")).get("untrusted_outputs", [])
    }
    outputs = [
        (name, unit, group, topic, (misfits[name], runs_topics.get(name)) if name in misfits else None)
        for name, unit, group, topic in outputs
    ]
    centre = json.loads(viewer.get("scene_centre_m", "[0, 0, 0]"))
    radius = float(viewer.get("scene_radius_m", "1"))
    return outputs, robot, centre, radius, read_sensitivities(path, totals)


def panel_title(name, unit):
    return f"{name} [{unit}]" if unit else name


def untrusted_title(title, relative_misfit, shows_runs):
    """As src/output/viewer/foxglove_layout.rs untrusted_title."""
    return f"⚠ {title} — NOT TRUSTED (misfit {100.0 * relative_misfit:.1f} %)" + (": true runs dotted" if shows_runs else "")


def sensitivity_view(output, topic, shown, dimensions):
    """A time-series view of one output's total Sobol' indices: every dimension is a series of the
    entity, only the shown ones visible, in the sensitivity colours."""
    entity = f"{topic}/position"
    colour = {j: SENSITIVITY_COLOURS[rank] for rank, (j, _) in enumerate(shown)}
    lines = rr.SeriesLines(
        colors=[rgba(colour.get(j, HIDDEN_SERIES_COLOUR)) for j in range(len(dimensions))],
        names=dimensions,
        widths=[1.5] * len(dimensions),
        visible_series=[j in colour for j in range(len(dimensions))],
    )
    return entity, rrb.TimeSeriesView(
        origin=entity,
        contents="$origin",
        name=f"{output}: total Sobol' index",
        overrides={entity: lines.visualizer()},
        plot_legend=rrb.Corner2D.RightTop,
    )


def build(outputs, robot, centre, radius, sensitivities=(), active_tab=None):
    elevation, azimuth = math.radians(CAMERA_ELEVATION_DEG), math.radians(CAMERA_AZIMUTH_DEG)
    distance = CAMERA_DISTANCE_IN_RADII * radius
    eye = [
        centre[0] + distance * math.cos(elevation) * math.cos(azimuth),
        centre[1] + distance * math.cos(elevation) * math.sin(azimuth),
        centre[2] + distance * math.sin(elevation),
    ]
    robot_root = f"/{robot}"
    robot_view = rrb.Spatial3DView(
        origin="/",
        name="nominal robot",
        contents=[f"+ {robot_root}/visual_geometries/**", "+ /tf"],
        eye_controls=rrb.EyeControls3D(position=eye, look_target=centre, eye_up=[0.0, 0.0, 1.0]),
    )
    groups = {}
    shown, runs_shown, titles = [], [], []
    for name, unit, group, topic, untrusted in outputs:
        entity = f"{topic}/position"
        shown.append(entity)
        lines = rr.SeriesLines(
            colors=[rgba(colour) for _, colour, _ in SERIES],
            names=[label for label, _, _ in SERIES],
            widths=[width for _, _, width in SERIES],
        )
        title, contents, overrides = panel_title(name, unit), [entity], {entity: lines.visualizer()}
        if untrusted is not None:
            misfit, runs_topic = untrusted
            title = untrusted_title(title, misfit, runs_topic is not None)
            if runs_topic is not None:
                runs_entity = f"{runs_topic}/position"
                runs_shown.append(runs_entity)
                contents.append(runs_entity)
                overrides[runs_entity] = rr.SeriesPoints(
                    colors=[rgba(colour) for _, colour in RUNS_SERIES],
                    names=[label for label, _ in RUNS_SERIES],
                    markers=["circle"] * len(RUNS_SERIES),
                    marker_sizes=[RUNS_MARKER_SIZE] * len(RUNS_SERIES),
                ).visualizer()
        titles.append(title)
        view = rrb.TimeSeriesView(
            origin=entity if len(contents) == 1 else "/",
            contents="$origin" if len(contents) == 1 else contents,
            name=title,
            overrides=overrides,
            plot_legend=rrb.Corner2D.RightTop,
        )
        groups.setdefault(group, []).append(view)
    ordered = sorted(groups.items(), key=lambda item: (group_rank(item[0]), item[0]))
    tabs = [rrb.Grid(*views, name=group) for group, views in ordered]
    names = [group for group, _ in ordered]
    # After every envelope tab: per group, its outputs' sensitivity views.
    sensitivity_groups, sensitivity_entities = {}, []
    for output, group, topic, ranked, dimensions in sensitivities:
        entity, view = sensitivity_view(output, topic, ranked, dimensions)
        sensitivity_entities.append(entity)
        sensitivity_groups.setdefault(group, []).append(view)
    for group, views in sorted(sensitivity_groups.items(), key=lambda item: (group_rank(item[0]), item[0])):
        tabs.append(rrb.Grid(*views, name=f"{group} · sensitivity"))
        names.append(f"{group} · sensitivity")
    if active_tab is not None and active_tab not in names:
        sys.exit(f"--active-tab {active_tab!r}: the log's groups are {names}")
    active = names.index(active_tab) if active_tab is not None else 0
    blueprint = rrb.Blueprint(
        rrb.Horizontal(robot_view, rrb.Tabs(*tabs, name="outputs", active_tab=active), column_shares=[35, 65]),
        rrb.TimePanel(timeline=TIMELINE, expanded=True),
        rrb.SelectionPanel(expanded=False),
        auto_views=False,
    )
    manifest = {
        "application_id": APPLICATION_ID,
        "timeline": TIMELINE,
        "robot_root": robot_root,
        "plotted_entities": shown,
        "runs_entities": runs_shown,
        "tabs": [group for group, _ in sorted(groups.items(), key=lambda item: (group_rank(item[0]), item[0]))],
        "titles": titles,
        "sensitivity_entities": sensitivity_entities,
        "sensitivity_tabs": [name for name in names if name.endswith(" · sensitivity")],
        "eye": eye,
        "look_target": centre,
    }
    return blueprint, manifest


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log")
    parser.add_argument("out")
    parser.add_argument("--manifest")
    parser.add_argument("--active-tab")
    args = parser.parse_args()
    outputs, robot, centre, radius, sensitivities = read_log(args.log)
    blueprint, manifest = build(outputs, robot, centre, radius, sensitivities, active_tab=args.active_tab)
    blueprint.save(APPLICATION_ID, args.out)
    if args.manifest:
        with open(args.manifest, "w") as f:
            json.dump(manifest, f, indent=2)


if __name__ == "__main__":
    main()
