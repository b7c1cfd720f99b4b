#!/usr/bin/env python3
"""Prints the Foxglove layout that ribbon attached to an MCAP log (docs/mcap.md §4).

Usage: extract_layout.py LOG.mcap > layout.json     (then Foxglove: Layouts → Import from file…)
Needs the Python `mcap` package (in the reference venv: target/reference-venv/bin/python).
"""

import sys

from mcap.reader import make_reader

LAYOUT_NAME = "foxglove-layout.json"


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    path = sys.argv[1]
    try:
        with open(path, "rb") as f:
            for attachment in make_reader(f).iter_attachments():
                if attachment.name == LAYOUT_NAME:
                    sys.stdout.write(attachment.data.decode("utf-8"))
                    return
    except OSError as e:
        sys.exit(f"{path}: cannot read: {e}")
    sys.exit(f"{path}: no attachment named {LAYOUT_NAME} (written by ribbon simulate/analyze --out)")


if __name__ == "__main__":
    main()
