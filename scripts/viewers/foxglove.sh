#!/usr/bin/env bash
# The Foxglove half of the viewer check (docs/mcap.md §8): writes the ur5 log, takes the layout
# ribbon attached to it, opens both in a built Foxglove-family web app (Lichtblick, the
# open-source continuation of Foxglove Studio) in headless Chromium on loopback, and saves a
# screenshot per tab of the layout, checked by foxglove_check.mjs.
#
# Needs: APP_DIR, the directory of a built Lichtblick (or Foxglove Studio ≤ 1.87) web app — no
#   registry this project reaches ships one built, so it is not installed here; the reference
#   venv (target/reference-venv, made by `cargo test`); Node.js with npm; and Debian's chromium
#   (apt-get install chromium).
# Usage: scripts/viewers/foxglove.sh APP_DIR [OUT_DIR]   (default target/viewer-check; the
# README's pictures are docs/images/foxglove-ur5-*.png, copied from there by hand after a look).
set -euo pipefail
cd "$(dirname "$0")/../.."
[ $# -ge 1 ] || { sed -n '2,13p' "$0" >&2; exit 2; }
app="$1"
out="${2:-target/viewer-check}"
venv=target/reference-venv/bin
[ -f "$app/index.html" ] || { echo "foxglove.sh: $app/index.html not found: APP_DIR must be a built web app" >&2; exit 2; }
for tool in node npm "${CHROMIUM:-/usr/bin/chromium}" "$venv/python"; do
    command -v "$tool" >/dev/null || { echo "foxglove.sh: $tool not found (see the header of $0)" >&2; exit 2; }
done
mkdir -p "$out/node"
[ -d "$out/node/node_modules/playwright-core" ] \
    || npm install --silent --prefix "$out/node" playwright-core@1.64.1 >/dev/null
cargo build --release --quiet
./target/release/ribbon analyze robots/ur5/ur5.urdf --out "$out/ur5.mcap" >/dev/null
"$venv/python" scripts/viewers/extract_layout.py "$out/ur5.mcap" >"$out/ur5.layout.json"
# Opened at t = 1 s: the legends read the envelope there, the 3D view shows the nominal pose.
# One picture per tab of the layout: foxglove-ur5-joint-positions.png, foxglove-ur5-frame-tool0.png.
NODE_PATH="$out/node/node_modules" node scripts/viewers/foxglove_check.mjs \
    "$app" "$out/ur5.mcap" "$out/ur5.layout.json" "$out/foxglove-ur5" 1.0
echo "screenshots in $out"
