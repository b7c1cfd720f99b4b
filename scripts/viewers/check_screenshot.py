#!/usr/bin/env python3
"""Asserts what a viewer screenshot can show, and writes a half-size copy for the README.

Usage: check_screenshot.py SHOT.png SMALL.png [--true-runs]

Checks (exit 1 on failure): the picture is at least 800 × 450 pixels; it is not blank (at least
COLOUR_SHARE of its pixels differ from the most common colour, the background); and each of the
three envelope colours of docs/mcap.md §4 (lower #0072b2, nominal #009e73, upper #d55e00) covers
at least MIN_SERIES_PIXELS pixels within COLOUR_TOLERANCE per channel, i.e. the three series are
drawn in their colours; with --true-runs (a log of an untrusted study), the dots of the true
runs' hull (#cc79a7, docs/mcap.md §4) too. Needs Pillow (in the reference venv).
"""

import sys
from collections import Counter

from PIL import Image

SERIES = {"lower": (0x00, 0x72, 0xB2), "nominal": (0x00, 0x9E, 0x73), "upper": (0xD5, 0x5E, 0x00)}
# Must match src/output/viewer/mod.rs RUNS_HULL_SERIES.
TRUE_RUNS = {"true runs": (0xCC, 0x79, 0xA7)}
# Anti-aliasing and the plots' own shading blend the colours; 24 of 255 per channel still tells
# the three apart (they differ by > 60 in some channel) and from the greys of the interface.
COLOUR_TOLERANCE = 24
# A line 1.5 px wide across a plot a few hundred px wide, at least once.
MIN_SERIES_PIXELS = 300
COLOUR_SHARE = 0.05


def main():
    shot, small = sys.argv[1], sys.argv[2]
    series = {**SERIES, **(TRUE_RUNS if "--true-runs" in sys.argv[3:] else {})}
    image = Image.open(shot).convert("RGB")
    width, height = image.size
    failures = []
    if width < 800 or height < 450:
        failures.append(f"{width} × {height} pixels, expected at least 800 × 450")
    pixels = list(image.get_flattened_data()) if hasattr(image, "get_flattened_data") else list(image.getdata())
    background, count = Counter(pixels).most_common(1)[0]
    if 1 - count / len(pixels) < COLOUR_SHARE:
        failures.append(f"blank: {count / len(pixels):.1%} of the pixels are the background {background}")
    for name, colour in series.items():
        near = sum(1 for p in pixels if all(abs(a - b) <= COLOUR_TOLERANCE for a, b in zip(p, colour)))
        if near < MIN_SERIES_PIXELS:
            failures.append(f"series {name}: {near} pixels near {colour}, expected ≥ {MIN_SERIES_PIXELS}")
        else:
            print(f"{shot}: {name} series, {near} pixels")
    if failures:
        print(f"check_screenshot.py: {shot}:", *failures, sep="\n  - ", file=sys.stderr)
        sys.exit(1)
    image.resize((width // 2, height // 2), Image.LANCZOS).save(small, optimize=True)
    print(f"{shot}: {width} × {height}, ok; half-size copy {small}")


if __name__ == "__main__":
    main()
