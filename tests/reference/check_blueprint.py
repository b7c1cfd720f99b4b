#!/usr/bin/env python3
"""Checks the rerun blueprint of scripts/viewers/rerun_blueprint.py against a fresh ribbon log.

Usage: check_blueprint.py LOG.mcap WORK_DIR

Converts LOG.mcap as the docs say (`rerun mcap convert --timeline-type duration --application-id
ribbon`), writes the blueprint and its manifest, and checks, each failure collected (exit 1):
- `rerun rrd print` reads the .rbl as a blueprint store of application `ribbon`;
- every entity the blueprint plots exists in the recording with one row of Scalars per record
  time of its MCAP channel (no empty plotted entity), and is an envelope's `…/position` entity;
- every view title carries its channel's unit; one tab per channel `group`;
- for a log of an untrusted study (the `ribbon` record's `check` entry): each untrusted output's
  view is titled `⚠ name [unit] — NOT TRUSTED (misfit X %)…` with its misfit, and plots the hull of
  its true runs (`/ribbon/runs/…/position`, one row per message of that channel);
- the robot's URDF geometry root is in the recording; the eye is finite and away from the target;
- the recording's `message_log_time` timeline is a duration (seconds from 0, not 1970).
"""

import json
import math
import re
import subprocess
import sys
from pathlib import Path

from mcap.reader import make_reader

HERE = Path(__file__).resolve().parent
SCRIPT = HERE.parent.parent / "scripts" / "viewers" / "rerun_blueprint.py"
CHUNK_LINE = re.compile(r"^Chunk\(\S+\) with (\d+) rows \([^)]*\) - (\S+) - data columns: \[(.*)\]$")
failures = []


def fail(message):
    failures.append(message)


def run(command):
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"`{' '.join(map(str, command))}` failed ({result.returncode}):\n{result.stderr[-3000:]}")
    return result.stdout


def check_rows(entities, channels, rows):
    """Each `…/position` entity holds one row of Scalars per message of its channel (`channels`:
    topic → (metadata, message count); `rows`: (entity, column) → rows in the recording)."""
    for entity in entities:
        topic = entity.removesuffix("/position")
        got = rows.get((entity, "Scalars:scalars"), 0)
        want = channels.get(topic, ({}, -1))[1]
        if got == 0 or got != want:
            fail(f"{entity}: {got} rows of Scalars in the recording, expected {want} (its channel's messages)")


def main():
    log, work = Path(sys.argv[1]), Path(sys.argv[2])
    work.mkdir(parents=True, exist_ok=True)
    rerun = str(Path(sys.executable).parent / "rerun")
    rrd, rbl, manifest_path = work / "log.rrd", work / "log.rbl", work / "manifest.json"
    run([rerun, "mcap", "convert", "--timeline-type", "duration", "--application-id", "ribbon", str(log), "-o", str(rrd)])
    run([sys.executable, str(SCRIPT), str(log), str(rbl), "--manifest", str(manifest_path)])
    manifest = json.loads(manifest_path.read_text())

    printed_rbl = run([rerun, "rrd", "print", str(rbl)])
    if "Blueprint" not in printed_rbl or '"ribbon"' not in printed_rbl:
        fail(f"the .rbl is not a blueprint store of application ribbon:\n{printed_rbl[:800]}")

    rows = {}
    for line in run([rerun, "rrd", "print", str(rrd)]).splitlines():
        match = CHUNK_LINE.match(line.strip())
        if match:
            for column in match.group(3).split():
                key = (match.group(2), column)
                rows[key] = rows.get(key, 0) + int(match.group(1))

    with open(log, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        counts = summary.statistics.channel_message_counts
        channels = {
            c.topic: (c.metadata, counts.get(c.id, 0))
            for c in summary.channels.values()
            if c.topic.startswith("/ribbon/envelope/")
        }
        runs_channels = {
            c.topic: (c.metadata, counts.get(c.id, 0))
            for c in summary.channels.values()
            if c.topic.startswith("/ribbon/runs/")
        }
        records = {m.name: m.metadata for m in reader.iter_metadata()}
    verdict = json.loads(records.get("ribbon", {}).get("check", "{}"))
    misfits = {entry["name"]: entry["relative_misfit"] for entry in verdict.get("untrusted_outputs", [])}
    if verdict and not misfits:
        fail(f"the `check` entry names no untrusted output: {verdict}")
    want_entities = {topic + "/position" for topic in channels}
    if set(manifest["plotted_entities"]) != want_entities:
        fail(f"plotted {sorted(manifest['plotted_entities'])}, expected one per envelope channel {sorted(want_entities)}")
    check_rows(manifest["plotted_entities"], channels, rows)
    titles = manifest["titles"]
    for topic, (metadata, _) in channels.items():
        unit = metadata.get("unit", "")
        title = f"{metadata['output']} [{unit}]" if unit else metadata["output"]
        if metadata["output"] in misfits:
            title = f"⚠ {title} — NOT TRUSTED (misfit {100.0 * misfits[metadata['output']]:.1f} %)"
            if runs_channels:
                title += ": true runs dotted"
        if title not in titles:
            fail(f"no view titled {title!r} for {topic} (titles: {titles})")
    want_runs = {
        topic + "/position" for topic, (metadata, _) in runs_channels.items() if metadata["output"] in misfits
    }
    if set(manifest["runs_entities"]) != want_runs:
        fail(f"true-run entities {sorted(manifest['runs_entities'])}, expected those of the untrusted outputs {sorted(want_runs)}")
    check_rows(manifest["runs_entities"], runs_channels, rows)
    groups = sorted({metadata["group"] for metadata, _ in channels.values()})
    if sorted(manifest["tabs"]) != groups:
        fail(f"tabs {manifest['tabs']}, expected one per group {groups}")
    # Sensitivity views: total-index entities of the log, each with its channel's rows, one tab
    # `GROUP · sensitivity` per group that has them.
    with open(log, "rb") as f:
        summary = make_reader(f).get_summary()
        counts = summary.statistics.channel_message_counts
        totals = {
            c.topic: (c.metadata, counts.get(c.id, 0))
            for c in summary.channels.values()
            if c.topic.startswith("/ribbon/sobol/total/")
        }
    for entity in manifest["sensitivity_entities"]:
        topic = entity.removesuffix("/position")
        got = rows.get((entity, "Scalars:scalars"), 0)
        want = totals.get(topic, ({}, -1))[1]
        if topic not in totals or got == 0 or got != want:
            fail(f"{entity}: {got} rows of Scalars in the recording, expected {want} (a total Sobol' channel's messages)")
    shown_groups = sorted({totals[e.removesuffix("/position")][0]["group"] for e in manifest["sensitivity_entities"] if e.removesuffix("/position") in totals})
    if sorted(manifest["sensitivity_tabs"]) != sorted(f"{g} · sensitivity" for g in shown_groups):
        fail(f"sensitivity tabs {manifest['sensitivity_tabs']}, expected one per group of {shown_groups}")
    if totals and not manifest["sensitivity_entities"]:
        fail("the log has total Sobol' channels but the blueprint shows none")
    root = manifest["robot_root"] + "/visual_geometries/"
    if not any(entity.startswith(root) for entity, _ in rows):
        fail(f"no robot geometry under {root} in the recording")
    eye, target = manifest["eye"], manifest["look_target"]
    if not all(math.isfinite(v) for v in eye + target) or math.dist(eye, target) <= 0:
        fail(f"eye {eye} looking at {target}")
    verbose = run([rerun, "rrd", "print", "-vv", str(rrd)])
    if "index_name: message_log_time" not in verbose or "type: Duration(ns)" not in verbose:
        fail("the recording has no duration timeline message_log_time")
    if re.search(r"message_log_time\s*┆[^\n]*\n[^\n]*type: Timestamp", verbose):
        fail("message_log_time is a timestamp timeline (1970-based)")

    if failures:
        print(f"check_blueprint.py: {len(failures)} check(s) failed for {log}:", file=sys.stderr)
        for message in failures:
            print(f"  - {message}", file=sys.stderr)
        sys.exit(1)
    print(f"check_blueprint.py: {log}: {len(manifest['plotted_entities'])} plotted entities, {len(manifest['runs_entities'])} true-run hulls, tabs {manifest['tabs']}: ok")


if __name__ == "__main__":
    main()
