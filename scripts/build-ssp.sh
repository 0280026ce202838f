#!/usr/bin/env bash
# Packs the plant FMU and a controller FMU, wired by examples/fmu/crawler.ssd, into an SSP 1.0
# file that FMI masters load (ecos, libcosim):
#   OUT_DIR/crawler.ssp   SystemStructure.ssd, resources/crawler_physics.fmu, resources/controller.fmu
# Usage: scripts/build-ssp.sh [--controller FMU] [PLANT_FMU [OUT_DIR]]
#   PLANT_FMU          the FMI 2.0 plant FMU (default target/fmu/crawler_physics.fmu, written by
#                      scripts/build-fmu.sh)
#   OUT_DIR            where crawler.ssp goes (default target/fmu)
#   --controller FMU   your own controller FMU instead of examples/fmu/wave_controller.py's; it must
#                      have the outputs wave_f0, wave_k, wave_omega and wave_phase (and the
#                      parameters f0 and omega the SSD's parameter set "crawler" gives it: edit a copy
#                      of examples/fmu/crawler.ssd, and pass it as SSD=FILE, for other names)
# Without --controller the wave controller is built with pythonfmu from the project's .venv
# (scripts/setup-python.sh). Needs python3 (its zipfile module packs the archive).
set -euo pipefail
cd "$(dirname "$0")/.."

usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; }
controller=""
args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --controller)
      if [ $# -lt 2 ]; then echo "build-ssp: --controller needs an FMU" >&2; exit 2; fi
      controller="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    -*) echo "build-ssp: unknown option $1" >&2; usage >&2; exit 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
if [ "${#args[@]}" -gt 2 ]; then echo "build-ssp: at most PLANT_FMU and OUT_DIR" >&2; exit 2; fi
plant="${args[0]:-target/fmu/crawler_physics.fmu}"
out="${args[1]:-target/fmu}"
ssd="${SSD:-examples/fmu/crawler.ssd}"
for f in "$plant" "$ssd" ${controller:+"$controller"}; do
  if [ ! -f "$f" ]; then
    echo "build-ssp: $f is missing$( [ "$f" = "$plant" ] && echo ' (scripts/build-fmu.sh writes it)' )" >&2
    exit 1
  fi
done

stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/resources"
cp "$ssd" "$stage/SystemStructure.ssd"
cp "$plant" "$stage/resources/crawler_physics.fmu"
if [ -n "$controller" ]; then
  cp "$controller" "$stage/resources/controller.fmu"
else
  bash scripts/setup-python.sh
  echo "build-ssp: building examples/fmu/wave_controller.py into an FMU (pythonfmu)..." >&2
  .venv/bin/python -m pythonfmu build -f examples/fmu/wave_controller.py -d "$stage" >&2
  mv "$stage/WaveController.fmu" "$stage/resources/controller.fmu"
fi
mkdir -p "$out"
python3 - "$stage" "$out/crawler.ssp" <<'PY'
import os, sys, zipfile
stage, archive = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
    for name in ("SystemStructure.ssd", "resources/crawler_physics.fmu", "resources/controller.fmu"):
        z.write(os.path.join(stage, name), name)
PY
echo "build-ssp: wrote $out/crawler.ssp" >&2
