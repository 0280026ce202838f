#!/usr/bin/env bash
# Opens a recording in the real Rerun viewer, headless (Xvfb + Mesa's lavapipe Vulkan driver), waits
# until the viewer has loaded all of it, and saves a PNG screenshot.
#   usage: scripts/screenshot.sh REC.rrd OUT.png [WIDTHxHEIGHT]
# Needs the venv's rerun-sdk (scripts/setup-python.sh --viewer) and Debian's xvfb, xauth and
# mesa-vulkan-drivers (scripts/setup-viewer.sh installs them).
#
# The viewer reads a file in the background while it draws, so a picture taken at a fixed moment
# shows however much it had read by then. This script takes it when the viewer has gone idle: its
# processes (viewer and X server) used less than a tenth of a core over each of three seconds in a
# row, which a viewer still reading or laying out data never does (at most 240 s), then asks the
# running viewer for the picture over its gRPC port (the SDK's ViewerClient).
set -euo pipefail
rec=${1:?usage: scripts/screenshot.sh REC.rrd OUT.png [WIDTHxHEIGHT]}
out=${2:?usage: scripts/screenshot.sh REC.rrd OUT.png [WIDTHxHEIGHT]}
size=${3:-1600x1000}
root=$(cd "$(dirname "$0")/.." && pwd)
viewer="$root/.venv/bin/rerun"
python="$root/.venv/bin/python"
[ -f "$rec" ] || { echo "error: no recording at $rec" >&2; exit 2; }
[ -x "$viewer" ] || { echo "error: $viewer missing; run scripts/setup-python.sh --viewer" >&2; exit 2; }
command -v xvfb-run >/dev/null || { echo "error: xvfb-run missing; run scripts/setup-viewer.sh" >&2; exit 2; }
command -v setsid >/dev/null || { echo "error: setsid missing (util-linux)" >&2; exit 2; }
icd=$(ls /usr/share/vulkan/icd.d/lvp_icd*.json 2>/dev/null | head -n1)
[ -n "$icd" ] || { echo "error: the lavapipe Vulkan driver is missing; run scripts/setup-viewer.sh" >&2; exit 2; }
rm -f "$out"
out_abs=$(cd "$(dirname "$out")" && pwd)/$(basename "$out")
port=$("$python" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
log=$(mktemp)
# its own session (and process group), so that it and everything it starts can be found and ended
CI=1 VK_ICD_FILENAMES="$icd" WGPU_BACKEND=vulkan setsid xvfb-run -a -s "-screen 0 ${size}x24" \
  "$viewer" --bind 127.0.0.1 --port "$port" --window-size "$size" "$rec" >"$log" 2>&1 &
sid=$!
trap 'kill -TERM -- "-$sid" 2>/dev/null || true; rm -f "$log"' EXIT
CI=1 "$python" - "$sid" "$port" "$out_abs" <<'PY'
import os, socket, sys, time

sid, port, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
tick = os.sysconf("SC_CLK_TCK")


def cpu_seconds():
    """CPU time of every process of the viewer's session, s."""
    total = 0
    for p in os.listdir("/proc"):
        if not p.isdigit():
            continue
        try:
            with open(f"/proc/{p}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid:  # session id
            total += int(fields[11]) + int(fields[12])  # utime + stime
    return total / tick


deadline = time.time() + 240
while True:  # the viewer listens once it is up
    try:
        socket.create_connection(("127.0.0.1", port), timeout=1).close()
        break
    except OSError:
        if time.time() > deadline:
            sys.exit("error: the viewer never listened")
        time.sleep(0.5)
idle, last = 0, cpu_seconds()
while idle < 3 and time.time() < deadline:
    time.sleep(1.0)
    now = cpu_seconds()
    idle = idle + 1 if now - last < 0.1 else 0
    last = now
if idle < 3:
    print("warning: the viewer was still busy after 240 s; the picture may be incomplete", file=sys.stderr)
from rerun.experimental import ViewerClient

ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy").save_screenshot(out)
for _ in range(100):
    if os.path.exists(out) and os.path.getsize(out) > 0:
        break
    time.sleep(0.1)
PY
if [ -s "$out" ]; then
  echo "$out"
else
  echo "error: the viewer wrote no screenshot to $out; its log:" >&2
  cat "$log" >&2
  exit 1
fi
