#!/usr/bin/env bash
# Opens a recording in the real Rerun viewer, headless (Xvfb + Mesa's lavapipe Vulkan driver), and
# saves a PNG screenshot.   usage: scripts/screenshot.sh REC.rrd OUT.png [WIDTHxHEIGHT]
# Needs the venv's rerun-sdk (scripts/setup-python.sh --viewer) and Debian's xvfb, xauth and
# mesa-vulkan-drivers (scripts/setup-viewer.sh installs them).
set -euo pipefail
rec=${1:?usage: scripts/screenshot.sh REC.rrd OUT.png [WIDTHxHEIGHT]}
out=${2:?usage: scripts/screenshot.sh REC.rrd OUT.png [WIDTHxHEIGHT]}
size=${3:-1600x1000}
root=$(cd "$(dirname "$0")/.." && pwd)
viewer="$root/.venv/bin/rerun"
[ -f "$rec" ] || { echo "error: no recording at $rec" >&2; exit 2; }
[ -x "$viewer" ] || { echo "error: $viewer missing; run scripts/setup-python.sh --viewer" >&2; exit 2; }
command -v xvfb-run >/dev/null || { echo "error: xvfb-run missing; run scripts/setup-viewer.sh" >&2; exit 2; }
icd=$(ls /usr/share/vulkan/icd.d/lvp_icd*.json 2>/dev/null | head -n1)
[ -n "$icd" ] || { echo "error: the lavapipe Vulkan driver is missing; run scripts/setup-viewer.sh" >&2; exit 2; }
rm -f "$out"
VK_ICD_FILENAMES="$icd" WGPU_BACKEND=vulkan timeout 300 xvfb-run -a -s "-screen 0 ${size}x24" \
  "$viewer" --bind 127.0.0.1 --window-size "$size" --screenshot-to "$out" "$rec" >/dev/null 2>&1 || true
if [ -s "$out" ]; then
  echo "$out"
else
  echo "error: the viewer wrote no screenshot to $out" >&2
  exit 1
fi
