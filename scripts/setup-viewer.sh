#!/usr/bin/env bash
# Installs what scripts/screenshot.sh needs to run the Rerun viewer headless on Debian/Ubuntu:
# the viewer itself (pinned, into .venv), Xvfb and Mesa's lavapipe (software Vulkan) driver.
# On a desktop you only need `scripts/setup-python.sh --viewer` and then `.venv/bin/rerun FILE.rrd`.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup-python.sh --viewer
need=()
command -v xvfb-run >/dev/null || need+=(xvfb xauth)
ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1 || need+=(mesa-vulkan-drivers)
if [ ${#need[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${need[@]}"
fi
echo "viewer ready: .venv/bin/rerun; headless screenshots: scripts/screenshot.sh REC.rrd OUT.png"
