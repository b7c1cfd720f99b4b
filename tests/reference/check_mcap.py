#!/usr/bin/env python3
"""Cross-checks an MCAP file written by ribbon against independent readers (design contract "MCAP").

Usage: check_mcap.py FILE.mcap EXPECTED.json [--work-dir DIR]

EXPECTED.json says what was written (numbers exactly as given to the writer):
    {
      "urdf_path": "...",                      # its text must be on /robot_description and attached
      "robot": "double_pendulum",              # the URDF's robot name (rerun's entity root)
      "envelopes": [{"name": "q.j1", "topic": "/ribbon/envelope/q/j1",
                     "time": [...], "lower": [...], "nominal": [...], "upper": [...]}],
      "errors":    [{"name": "q.j1", "topic": "/ribbon/error/q/j1", "time": [...], "estimate": [...]}],
      "sobol":     [{"name": "q.j1", "topic": "/ribbon/sobol/main/q/j1", "index": "main",   # optional
                     "dimensions": ["l1", ...], "time": [...], "values": [[...per dimension], ...]}],
      # An untrusted study's log (exit 4) also has, per output, the hull of its true runs, and
      # names the outputs the check did not trust (both optional, docs/mcap.md §1, §4):
      "runs":      [{"name": "q.j1", "topic": "/ribbon/runs/q/j1", "time": [...],
                     "runs_lower": [...], "runs_upper": [...]}],
      "untrusted_outputs": ["q.j1", ...],
      "transforms": [{"time": t, "frames": [{"link": "bar1", "parent": "base", "translation": [x, y, z],
                                              "rotation": [x, y, z, w]}]}],   # parent default "world"
      # or, when the poses are not known to the caller (a `ribbon analyze` run), instead of
      # "transforms": "transform_times": [t, ...], "transform_links": ["bar1", ...] — every /tf
      # message is then decoded and its time and child frames checked, and each parent against the
      # URDF's joint tree (parsed here: the parent link of the joint whose child the link is, `world`
      # for the root), not its numbers.
      "metadata": {"robot": ..., "method": ..., "order": ..., "runs": ..., "ribbon_version": ...,
                   "partial": "true|false", "parameters": "<JSON text>"},
      "attachments": [{"name": ..., "media_type": ..., "path": "<file with the expected bytes>"}],
      # an attachment with "foxglove_layout": true instead of "path" must be a Foxglove layout whose
      # Plot paths name only envelope topics of the file (fields position[0..2], labelled lower,
      # nominal, upper) — or, in a sensitivity plot, total Sobol' topics of the file (position[j]
      # labelled with dimension j's name) — and whose 3D panel takes the URDF from /robot_description.
      # The plot of an output in "untrusted_outputs" also has the hull series of the same output
      # (position[0..1] of its /ribbon/runs/ topic, a topic of the file and of "runs", labelled
      # "true runs, lowest" / "true runs, highest") and a title that starts with ⚠ and says NOT
      # TRUSTED; every other plot has neither.
      "viewer": true   # optional: `scene_centre_m` and a positive `scene_radius_m` in the `ribbon` record,
                       # and the first message at log time 0
    }
Envelope entries may carry "unit": the channel metadata must then hold it (and the output name).

Checks, each failure collected and reported (exit 1):
- Python `mcap` reads the file through its summary (lz4 chunks, chunk indexes, statistics) and
  decodes every message: CDR with `mcap-ros2-support`, protobuf with `mcap-protobuf-support`;
- every JointState decodes to exactly the numbers given, names [lower, nominal, upper],
  [estimate] or [runs_lower, runs_upper] (a Sobol' channel: the dimensions' names, channel
  metadata `index` and `unit` ""),
  header.stamp = log time = publish time = round(time * 1e9);
- every /tf message decodes to the frames given, and re-encoding them with foxglove-sdk's
  `foxglove.messages.FrameTransforms` gives the same bytes;
- the `foxglove.FrameTransforms` schema record equals, byte for byte, the one foxglove-sdk writes
  into an MCAP of its own (and its `get_schema()`);
- /robot_description holds the URDF once at t = 0; the `ribbon` metadata record and the attachments
  are as given;
- `rerun mcap convert` accepts the file and `rerun rrd print` shows `Scalars` for every envelope,
  error and hull channel, `Transform3D` for /tf (one row per frame given), and visual geometry for every URDF
  link that has a <visual>.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

import foxglove
from foxglove.channels import FrameTransformsChannel
from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Timestamp, Vector3

NANOS_PER_SECOND = 1_000_000_000
# A time given in seconds maps to the nearest nanosecond; Python's round() breaks ties to even
# where Rust rounds away from zero, so accept either neighbour of an exact tie.
TIME_TOLERANCE_NS = 0.5
# rerun archetypes that a URDF <visual> becomes.
GEOMETRY_ARCHETYPES = ("Boxes3D", "Cylinders3D", "Ellipsoids3D", "Capsules3D", "Mesh3D", "Asset3D")

failures = []


def fail(message):
    failures.append(message)


def same_time(log_time_ns, time_s):
    return abs(log_time_ns - time_s * NANOS_PER_SECOND) <= TIME_TOLERANCE_NS


def foxglove_frame_transforms_schema(work_dir):
    """The FrameTransforms schema record that foxglove-sdk writes into an MCAP of its own."""
    path = Path(work_dir) / "foxglove_sdk_frame_transforms.mcap"
    writer = foxglove.open_mcap(str(path), allow_overwrite=True)
    channel = FrameTransformsChannel("/tf")
    channel.log(FrameTransforms(transforms=[]), log_time=0)
    writer.close()
    with open(path, "rb") as f:
        schemas = [s for s in make_reader(f).get_summary().schemas.values()]
    named = [s for s in schemas if s.name == "foxglove.FrameTransforms"]
    if len(named) != 1:
        raise SystemExit(f"foxglove-sdk wrote schemas {[s.name for s in schemas]}, not one foxglove.FrameTransforms")
    return named[0]


def foxglove_encode(transforms_entry):
    """What foxglove-sdk encodes for one /tf message of the expected frames."""
    t = transforms_entry["time"]
    ns = round(t * NANOS_PER_SECOND)
    stamp = Timestamp(sec=ns // NANOS_PER_SECOND, nsec=ns % NANOS_PER_SECOND)
    return FrameTransforms(
        transforms=[
            FrameTransform(
                timestamp=stamp,
                parent_frame_id=frame.get("parent", "world"),
                child_frame_id=frame["link"],
                translation=Vector3(x=frame["translation"][0], y=frame["translation"][1], z=frame["translation"][2]),
                rotation=Quaternion(
                    x=frame["rotation"][0], y=frame["rotation"][1], z=frame["rotation"][2], w=frame["rotation"][3]
                ),
            )
            for frame in transforms_entry["frames"]
        ]
    ).encode()


def check_file(mcap_path, expected, work_dir):
    with open(mcap_path, "rb") as f:
        reader = make_reader(f, decoder_factories=[Ros2DecoderFactory(), ProtobufDecoderFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        if summary is None:
            fail("no summary section")
            return {}
        if not header.library.startswith("ribbon "):
            fail(f"header library is {header.library!r}, expected 'ribbon <version> (...)'")
        if not summary.chunk_indexes:
            fail("no chunk indexes")
        compressions = {c.compression for c in summary.chunk_indexes}
        if compressions != {"lz4"}:
            fail(f"chunk compressions are {compressions}, expected only lz4")
        if summary.statistics is None:
            fail("no statistics record")

        channels_by_topic = {c.topic: c for c in summary.channels.values()}
        schemas = summary.schemas
        sobol = expected.get("sobol", [])
        runs = expected.get("runs", [])
        expected_topics = {e["topic"] for e in expected["envelopes"]} | {e["topic"] for e in expected["errors"]}
        expected_topics |= {e["topic"] for e in sobol} | {e["topic"] for e in runs}
        expected_topics |= {"/tf", "/robot_description"}
        if set(channels_by_topic) != expected_topics:
            fail(f"topics {sorted(channels_by_topic)} differ from the expected {sorted(expected_topics)}")

        # Schemas.
        def schema_of(topic):
            channel = channels_by_topic.get(topic)
            return schemas.get(channel.schema_id) if channel else None

        for entry in sobol:
            channel = channels_by_topic.get(entry["topic"])
            if channel is not None and (
                channel.metadata.get("index") != entry["index"] or channel.metadata.get("unit") != ""
            ):
                fail(f"{entry['topic']}: channel metadata {channel.metadata}, expected index = {entry['index']}, unit ''")
        for entry in expected["envelopes"] + expected["errors"] + sobol + runs:
            schema = schema_of(entry["topic"])
            channel = channels_by_topic.get(entry["topic"])
            if schema is None:
                fail(f"{entry['topic']}: no channel or schema")
                continue
            if (schema.name, schema.encoding, channel.message_encoding) != (
                "sensor_msgs/msg/JointState",
                "ros2msg",
                "cdr",
            ):
                fail(f"{entry['topic']}: schema {schema.name}/{schema.encoding}, encoding {channel.message_encoding}")
            if channel.metadata.get("output") != entry["name"]:
                fail(f"{entry['topic']}: channel metadata {channel.metadata}, expected output = {entry['name']}")
        joint_state = next((s for s in schemas.values() if s.name == "sensor_msgs/msg/JointState"), None)
        if joint_state is not None:
            text = joint_state.data.decode()
            separator = "=" * 80 + "\n"
            for dependency in ("std_msgs/Header", "builtin_interfaces/Time"):
                if f"{separator}MSG: {dependency}\n" not in text:
                    fail(f"JointState schema lacks the dependency block 'MSG: {dependency}'")
        tf_schema = schema_of("/tf")
        if tf_schema is None:
            fail("/tf: no channel or schema")
        else:
            reference = foxglove_frame_transforms_schema(work_dir)
            if (tf_schema.name, tf_schema.encoding) != ("foxglove.FrameTransforms", "protobuf"):
                fail(f"/tf schema is {tf_schema.name}/{tf_schema.encoding}")
            if tf_schema.data != reference.data:
                fail(
                    f"/tf schema data ({len(tf_schema.data)} bytes) differs from foxglove-sdk's "
                    f"({len(reference.data)} bytes); first difference at byte "
                    f"{next((i for i, (a, b) in enumerate(zip(tf_schema.data, reference.data)) if a != b), min(len(tf_schema.data), len(reference.data)))}"
                )
            if reference.data != FrameTransforms.get_schema().data:
                fail("foxglove-sdk's MCAP schema record differs from its own FrameTransforms.get_schema()")
            if reference.encoding != tf_schema.encoding:
                fail(f"foxglove-sdk writes schema encoding {reference.encoding}, the file {tf_schema.encoding}")

        # Every message, decoded.
        decoded = {}
        count = 0
        for schema, channel, message, value in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append((message, value))
            count += 1
        if summary.statistics is not None and count != summary.statistics.message_count:
            fail(f"decoded {count} messages, the statistics say {summary.statistics.message_count}")

        for entry, names in (
            [(e, ["lower", "nominal", "upper"]) for e in expected["envelopes"]]
            + [(e, ["estimate"]) for e in expected["errors"]]
            + [(e, e["dimensions"]) for e in sobol]
            + [(e, ["runs_lower", "runs_upper"]) for e in runs]
        ):
            topic = entry["topic"]
            got = decoded.get(topic, [])
            if len(got) != len(entry["time"]):
                fail(f"{topic}: {len(got)} messages, expected {len(entry['time'])}")
                continue
            if "values" in entry:
                # A Sobol' channel: one row of values per message, one value per dimension.
                columns = [[row[j] for row in entry["values"]] for j in range(len(names))]
            else:
                columns = [entry[n] for n in names]
            for i, (message, value) in enumerate(got):
                t = entry["time"][i]
                stamp_ns = value.header.stamp.sec * NANOS_PER_SECOND + value.header.stamp.nanosec
                if not (same_time(message.log_time, t) and message.publish_time == message.log_time == stamp_ns):
                    fail(
                        f"{topic}[{i}]: log {message.log_time}, publish {message.publish_time}, stamp {stamp_ns} ns;"
                        f" expected all = {t} s"
                    )
                if list(value.name) != names:
                    fail(f"{topic}[{i}]: names {list(value.name)}, expected {names}")
                want = [c[i] for c in columns]
                if list(value.position) != want:
                    fail(f"{topic}[{i}] at t = {t}: position {list(value.position)}, expected {want}")
                if list(value.velocity) or list(value.effort):
                    fail(f"{topic}[{i}]: velocity/effort not empty")

        urdf_root = ET.parse(expected["urdf_path"]).getroot()
        urdf_parents = {
            joint.find("child").get("link"): joint.find("parent").get("link") for joint in urdf_root.findall("joint")
        }
        got = decoded.get("/tf", [])
        if "transforms" not in expected:
            times, links = expected["transform_times"], expected["transform_links"]
            if len(got) != len(times):
                fail(f"/tf: {len(got)} messages, expected {len(times)}")
            for i, ((message, value), t) in enumerate(zip(got, times)):
                if not same_time(message.log_time, t):
                    fail(f"/tf[{i}]: log time {message.log_time} ns, expected {t} s")
                children = [transform.child_frame_id for transform in value.transforms]
                parents = [transform.parent_frame_id for transform in value.transforms]
                want_parents = [urdf_parents.get(link, "world") for link in links]
                if children != links or parents != want_parents:
                    fail(f"/tf[{i}]: frames {parents} -> {children}, expected {want_parents} -> {links} (the URDF tree)")
            check_chain_against_frame_outputs(got, times, expected)
            expected["transforms"] = [{"time": t, "frames": [{"link": link} for link in links]} for t in times]
            check_values = False
        else:
            check_values = True
        if check_values and len(got) != len(expected["transforms"]):
            fail(f"/tf: {len(got)} messages, expected {len(expected['transforms'])}")
        for i, ((message, value), entry) in enumerate(zip(got, expected["transforms"] if check_values else [])):
            if not same_time(message.log_time, entry["time"]) or message.publish_time != message.log_time:
                fail(f"/tf[{i}]: log {message.log_time} / publish {message.publish_time} ns, expected {entry['time']} s")
            if message.data != foxglove_encode(entry):
                fail(f"/tf[{i}]: payload differs from foxglove-sdk's encoding of the same frames")
            if len(value.transforms) != len(entry["frames"]):
                fail(f"/tf[{i}]: {len(value.transforms)} transforms, expected {len(entry['frames'])}")
                continue
            for transform, frame in zip(value.transforms, entry["frames"]):
                stamp_ns = transform.timestamp.seconds * NANOS_PER_SECOND + transform.timestamp.nanos
                got_frame = (
                    transform.parent_frame_id,
                    transform.child_frame_id,
                    [transform.translation.x, transform.translation.y, transform.translation.z],
                    [transform.rotation.x, transform.rotation.y, transform.rotation.z, transform.rotation.w],
                )
                want_frame = (frame.get("parent", "world"), frame["link"], frame["translation"], frame["rotation"])
                if got_frame != want_frame or stamp_ns != message.log_time:
                    fail(f"/tf[{i}]: decoded {got_frame} at {stamp_ns} ns, expected {want_frame} at {message.log_time} ns")

        urdf_text = Path(expected["urdf_path"]).read_text()
        got = decoded.get("/robot_description", [])
        if len(got) != 1:
            fail(f"/robot_description: {len(got)} messages, expected 1")
        else:
            message, value = got[0]
            if message.log_time != 0 or value.data != urdf_text:
                fail(f"/robot_description: log time {message.log_time}, text equal to the URDF: {value.data == urdf_text}")
            schema = schema_of("/robot_description")
            if schema is None or (schema.name, schema.encoding) != ("std_msgs/msg/String", "ros2msg"):
                fail(f"/robot_description schema is {schema and (schema.name, schema.encoding)}")

        metadata = [m for m in reader.iter_metadata() if m.name == "ribbon"]
        if len(metadata) != 1:
            fail(f"{len(metadata)} `ribbon` metadata records, expected 1")
        elif metadata[0].metadata != expected["metadata"]:
            fail(f"metadata {metadata[0].metadata} differs from the expected {expected['metadata']}")
        else:
            json.loads(metadata[0].metadata["parameters"])  # must parse

        if expected.get("viewer"):
            if summary.statistics is not None and summary.statistics.message_start_time != 0:
                fail(f"first log time {summary.statistics.message_start_time} ns, expected 0 (simulation time)")
            viewer = [m for m in reader.iter_metadata() if m.name == "ribbon"]
            if len(viewer) != 1:
                fail(f"{len(viewer)} `ribbon` metadata records, expected 1")
            else:
                centre = json.loads(viewer[0].metadata.get("scene_centre_m", "null"))
                radius = float(viewer[0].metadata.get("scene_radius_m", "nan"))
                if not (isinstance(centre, list) and len(centre) == 3 and radius > 0):
                    fail(f"`ribbon` record {viewer[0].metadata}: expected scene_centre_m [x, y, z] and scene_radius_m > 0")

        for entry in expected["envelopes"]:
            if "unit" not in entry:
                continue
            channel = next((c for c in summary.channels.values() if c.topic == entry["topic"]), None)
            want = {"output": entry["name"], "unit": entry["unit"]}
            got_meta = {k: channel.metadata.get(k) for k in want} if channel else None
            if got_meta != want:
                fail(f"{entry['topic']}: channel metadata {channel and channel.metadata}, expected {want}")

        attachments = {a.name: a for a in reader.iter_attachments()}
        want_names = {a["name"] for a in expected["attachments"]}
        if set(attachments) != want_names:
            fail(f"attachments {sorted(attachments)}, expected {sorted(want_names)}")
        for a in expected["attachments"]:
            got = attachments.get(a["name"])
            if got is not None and a.get("foxglove_layout"):
                check_foxglove_layout(got, {c.topic for c in summary.channels.values()}, expected)
            elif got is not None and (got.media_type != a["media_type"] or got.data != Path(a["path"]).read_bytes()):
                fail(f"attachment {a['name']}: media type {got.media_type}, bytes equal: {got.data == Path(a['path']).read_bytes()}")
        return {topic: len(v) for topic, v in decoded.items()}


# Composing a chain of /tf transforms in float64 against ribbon's own world placement of the frame:
# a few rounding errors per link, far below this (m).
CHAIN_TOLERANCE_M = 1e-9


def quaternion_rotate(q, v):
    """Rotates v by the unit quaternion q = [x, y, z, w]."""
    x, y, z, w = q
    # v + 2 w (u × v) + 2 u × (u × v), u = (x, y, z)
    cx, cy, cz = y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]
    ccx, ccy, ccz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    return [v[0] + 2 * (w * cx + ccx), v[1] + 2 * (w * cy + ccy), v[2] + 2 * (w * cz + ccz)]


def quaternion_multiply(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]


def check_chain_against_frame_outputs(tf_messages, times, expected):
    """Walks each /tf message's parent chain up to `world` for every link that has `frame.LINK.x|y|z`
    envelopes, and compares the composed origin with the envelopes' nominal values at that time."""
    wanted = {}
    for entry in expected["envelopes"]:
        parts = entry["name"].split(".")
        if len(parts) == 3 and parts[0] == "frame" and parts[2] in ("x", "y", "z"):
            wanted.setdefault(parts[1], {})["xyz".index(parts[2])] = entry["nominal"]
    for i, ((_, value), t) in enumerate(zip(tf_messages, times)):
        by_child = {tr.child_frame_id: tr for tr in value.transforms}
        for link, axes in wanted.items():
            position, rotation, frame, hops = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], link, 0
            # world_from_link = parent chain applied from the link upwards
            while frame != "world" and hops <= len(by_child):
                tr = by_child.get(frame)
                if tr is None:
                    fail(f"/tf[{i}]: frame {frame} (on the chain of {link}) has no transform")
                    break
                q = [tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w]
                rotated = quaternion_rotate(q, position)
                position = [rotated[k] + [tr.translation.x, tr.translation.y, tr.translation.z][k] for k in range(3)]
                rotation = quaternion_multiply(q, rotation)
                frame, hops = tr.parent_frame_id, hops + 1
            if frame != "world":
                fail(f"/tf[{i}]: the chain of {link} does not reach world")
                continue
            for axis, nominal in axes.items():
                if abs(position[axis] - nominal[i]) > CHAIN_TOLERANCE_M:
                    fail(f"/tf[{i}] at t = {t}: {link} composed along its chain is at {position}, but frame.{link}.{'xyz'[axis]} nominal is {nominal[i]}")


PLOT_PATH = re.compile(r'^(?P<topic>/[^.\s"]+)\.position\[(?P<index>\d+)\]$')
SOBOL_TOTAL_PREFIX = "/ribbon/sobol/total/"
ENVELOPE_PREFIX = "/ribbon/envelope/"
RUNS_PREFIX = "/ribbon/runs/"
# The hull series of an untrusted output's plot, by position index (src/output/viewer/mod.rs).
RUNS_LABELS = [(0, "true runs, lowest"), (1, "true runs, highest")]


def check_sensitivity_panel(panel_id, panel, topics, sobol):
    """A sensitivity Plot: every path is position[j] of one total-index topic of the file, j a
    dimension of its channel, labelled with that dimension's name; titled after the output."""
    paths = panel.get("paths", [])
    if not paths:
        fail(f"layout {panel_id}: a sensitivity plot without series")
    for path in paths:
        match = PLOT_PATH.match(path.get("value", ""))
        if not match or not match["topic"].startswith(SOBOL_TOTAL_PREFIX) or match["topic"] not in topics:
            fail(f"layout {panel_id}: path {path.get('value')!r} does not name a total Sobol' topic of the file")
            continue
        entry = sobol.get(match["topic"])
        if entry is None:
            continue  # the caller did not say what the topic holds; the topic exists
        index = int(match["index"])
        if index >= len(entry["dimensions"]) or path.get("label") != entry["dimensions"][index]:
            fail(f"layout {panel_id}: series {index} labelled {path.get('label')!r}, dimensions {entry['dimensions']}")
        title = f"{entry['name']}: total Sobol' index"
        if panel.get("foxglovePanelTitle") != title:
            fail(f"layout {panel_id}: titled {panel.get('foxglovePanelTitle')!r}, expected {title!r}")


def check_foxglove_layout(attachment, topics, expected):
    """The Foxglove layout attachment: valid JSON of the layout shape, one Plot per envelope channel
    (paths into existing topics, lower/nominal/upper), a 3D panel on /robot_description, every
    panel of configById placed in the layout tree (directly or in a tab)."""
    if attachment.media_type != "application/json":
        fail(f"layout attachment media type {attachment.media_type}, expected application/json")
    try:
        layout = json.loads(attachment.data)
    except ValueError as e:
        fail(f"layout attachment is not JSON: {e}")
        return
    config = layout.get("configById", {})
    plotted = {}
    sobol = {e["topic"]: e for e in expected.get("sobol", [])}
    runs_topics = {e["topic"] for e in expected.get("runs", [])}
    untrusted_topics = {
        e["topic"] for e in expected["envelopes"] if e["name"] in expected.get("untrusted_outputs", [])
    }
    for panel_id, panel in config.items():
        if not panel_id.startswith("Plot!"):
            continue
        if panel_id.startswith("Plot!ribbon-sobol"):
            check_sensitivity_panel(panel_id, panel, topics, sobol)
            continue
        labels, runs_labels, envelope_topics, hull_topics = [], [], set(), set()
        for path in panel.get("paths", []):
            match = PLOT_PATH.match(path.get("value", ""))
            if not match or match["topic"] not in topics:
                fail(f"layout {panel_id}: path {path.get('value')!r} does not name an envelope topic of the file")
                continue
            if match["topic"].startswith(RUNS_PREFIX):
                if match["topic"] not in runs_topics:
                    fail(f"layout {panel_id}: path {path.get('value')!r} names a hull topic the study did not write")
                runs_labels.append((int(match["index"]), path.get("label")))
                hull_topics.add(match["topic"])
                continue
            labels.append((int(match["index"]), path.get("label")))
            envelope_topics.add(match["topic"])
            plotted.setdefault(match["topic"], panel.get("foxglovePanelTitle", ""))
        if sorted(labels) != [(0, "lower"), (1, "nominal"), (2, "upper")]:
            fail(f"layout {panel_id}: series {labels}, expected lower, nominal, upper at position[0..2]")
        title = panel.get("foxglovePanelTitle", "")
        untrusted = bool(envelope_topics & untrusted_topics)
        if untrusted:
            want_hull = {t.replace(ENVELOPE_PREFIX, RUNS_PREFIX, 1) for t in envelope_topics}
            if sorted(runs_labels) != RUNS_LABELS or hull_topics != want_hull:
                fail(
                    f"layout {panel_id}: hull series {runs_labels} on {sorted(hull_topics)}, expected "
                    f"{RUNS_LABELS} on {sorted(want_hull)} (an untrusted output's true runs)"
                )
            if not (title.startswith("⚠") and "NOT TRUSTED" in title):
                fail(f"layout {panel_id}: an untrusted output's plot is titled {title!r}, without ⚠ … NOT TRUSTED")
        elif runs_labels or "NOT TRUSTED" in title:
            fail(f"layout {panel_id}: a trusted output's plot {title!r} has hull series {runs_labels} or says NOT TRUSTED")
    for entry in expected["envelopes"]:
        title = plotted.get(entry["topic"])
        if title is None:
            fail(f"layout: no Plot for {entry['topic']}")
        elif "unit" in entry and entry["unit"] and f"[{entry['unit']}]" not in title:
            fail(f"layout: the Plot of {entry['topic']} is titled {title!r}, without its unit [{entry['unit']}]")
    threes = [p for i, p in config.items() if i.startswith("3D!")]
    urdf_topics = [
        layer.get("topic") for p in threes for layer in p.get("layers", {}).values() if layer.get("layerId") == "foxglove.Urdf"
    ]
    if urdf_topics != ["/robot_description"]:
        fail(f"layout: 3D URDF layers on {urdf_topics}, expected one on /robot_description")
    placed = set(re.findall(r'"([A-Za-z0-9]+![^"]+)"', json.dumps(layout["layout"])))
    for tab in (p for i, p in config.items() if i.startswith("Tab!")):
        placed |= set(re.findall(r'"([A-Za-z0-9]+![^"]+)"', json.dumps(tab.get("tabs", []))))
    if placed != set(config):
        fail(f"layout: panels {sorted(set(config) - placed)} are configured but not placed, {sorted(placed - set(config))} placed but not configured")


def rerun_binary():
    """The `rerun` CLI of the rerun-sdk installed beside this interpreter."""
    candidate = Path(sys.executable).parent / "rerun"
    return str(candidate) if candidate.exists() else "rerun"


def run(command):
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(
            f"`{' '.join(command)}` failed with exit code {result.returncode}\n"
            f"stderr:\n{result.stderr[-4000:]}\nstdout:\n{result.stdout[-4000:]}"
        )
    return result.stdout


CHUNK_LINE = re.compile(r"^Chunk\(\S+\) with (\d+) rows \([^)]*\) - (\S+) - data columns: \[(.*)\]$")


def check_rerun(mcap_path, expected, work_dir):
    rerun = rerun_binary()
    rrd = Path(work_dir) / (Path(mcap_path).stem + ".rrd")
    run([rerun, "mcap", "convert", str(mcap_path), "-o", str(rrd)])
    printed = run([rerun, "rrd", "print", str(rrd)])
    (Path(work_dir) / (rrd.stem + ".print.txt")).write_text(printed)
    # entity -> {archetype:component -> rows}
    entities = {}
    for line in printed.splitlines():
        match = CHUNK_LINE.match(line.strip())
        if not match:
            continue
        rows, entity, columns = int(match.group(1)), match.group(2), match.group(3).split()
        for column in columns:
            entities.setdefault(entity, {}).setdefault(column, 0)
            entities[entity][column] += rows
    if not entities:
        fail(f"`rerun rrd print` listed no chunks; output head:\n{printed[:2000]}")
        return entities

    for entry in expected["envelopes"] + expected["errors"] + expected.get("runs", []):
        entity = entry["topic"] + "/position"
        rows = entities.get(entity, {}).get("Scalars:scalars", 0)
        if rows != len(entry["time"]):
            fail(f"rerun: {entity} has {rows} rows of Scalars:scalars, expected {len(entry['time'])}")
        if "SeriesLines:names" not in entities.get(entity, {}):
            fail(f"rerun: {entity} has no SeriesLines:names")

    frames = sum(len(t["frames"]) for t in expected["transforms"])
    tf = entities.get("/tf", {})
    for column in ("Transform3D:child_frame", "Transform3D:parent_frame", "Transform3D:translation", "Transform3D:quaternion"):
        if tf.get(column, 0) != frames:
            fail(f"rerun: /tf has {tf.get(column, 0)} rows of {column}, expected {frames} (one per frame)")

    root = ET.parse(expected["urdf_path"]).getroot()
    robot = root.get("name")
    for link in root.findall("link"):
        if link.find("visual") is None:
            continue
        prefix = f"/{robot}/visual_geometries/{link.get('name')}/"
        found = [
            column
            for entity, columns in entities.items()
            if entity.startswith(prefix)
            for column in columns
            if column.split(":")[0] in GEOMETRY_ARCHETYPES
        ]
        if not found:
            fail(f"rerun: no visual geometry under {prefix} for URDF link {link.get('name')}")
    return entities


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("mcap")
    parser.add_argument("expected")
    parser.add_argument("--work-dir", help="where the .rrd and foxglove-sdk's reference MCAP go (default: a temp dir)")
    args = parser.parse_args()
    expected = json.loads(Path(args.expected).read_text())
    with tempfile.TemporaryDirectory() as tmp:
        work_dir = args.work_dir or tmp
        os.makedirs(work_dir, exist_ok=True)
        try:
            counts = check_file(args.mcap, expected, work_dir)
            readable = True
        except Exception as e:  # a reader error is a finding, reported like the others
            fail(f"Python mcap could not read the file: {type(e).__name__}: {e}")
            counts, readable = {}, False
        entities = check_rerun(args.mcap, expected, work_dir) if readable else {}
    if failures:
        print(f"check_mcap.py: {len(failures)} check(s) failed for {args.mcap}:", file=sys.stderr)
        for message in failures[:50]:
            print(f"  - {message}", file=sys.stderr)
        if len(failures) > 50:
            print(f"  … and {len(failures) - 50} more", file=sys.stderr)
        sys.exit(1)
    print(f"check_mcap.py: {args.mcap} ok")
    print("  messages decoded per topic: " + ", ".join(f"{t} {n}" for t, n in sorted(counts.items())))
    geometry = sorted(
        {f"{e} {c.split(':')[0]}" for e, cs in entities.items() for c in cs if c.split(":")[0] in GEOMETRY_ARCHETYPES}
    )
    print("  rerun: Scalars on " + ", ".join(sorted(e for e, cs in entities.items() if "Scalars:scalars" in cs and e.endswith("/position"))))
    print("  rerun: Transform3D rows on /tf: " + str(entities.get("/tf", {}).get("Transform3D:translation", 0)))
    print("  rerun: visual geometry: " + "; ".join(geometry))


if __name__ == "__main__":
    main()
