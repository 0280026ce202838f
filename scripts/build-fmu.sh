#!/usr/bin/env bash
# Builds the plant's FMUs into OUT_DIR (default: target/fmu):
#   crawler_physics.fmu       FMI 2.0 co-simulation, binaries/linux64/crawler_physics.so
#   crawler_plant_fmi3.fmu  FMI 3.0 co-simulation, binaries/x86_64-linux/crawler_physics.so
# each with the modelDescription.xml and documentation/index.html that `crawler-fmu files`
# writes from the defaults the library itself uses (the paper scenario).
#
# Options:
#   --portable   build for any x86-64 CPU (baseline x86-64, about 2x slower plant) instead of
#                the workspace's x86-64-v3 (AVX2, FMA: Intel Haswell / AMD Excavator, 2013, and
#                later), in a separate target directory (target/portable)
#   --prebuilt   do not run cargo: package the libcrawler_fmu.so and crawler-fmu that
#                `cargo build --release -p crawler-fmu` left in the target directory
#                ($CARGO_TARGET_DIR or target; with --portable, its portable/ subdirectory and
#                RUSTFLAGS="-C target-cpu=x86-64"). `cargo test` does not leave the shared library
#                there; the tests run this script without --prebuilt.
# Needs: Linux on x86-64, cargo, python3 (its zipfile module packs the archives).
set -euo pipefail
cd "$(dirname "$0")/.."

usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; }
portable=0
prebuilt=0
out=""
for a in "$@"; do
  case "$a" in
    --portable) portable=1 ;;
    --prebuilt) prebuilt=1 ;;
    -h|--help) usage; exit 0 ;;
    -*) echo "build-fmu: unknown option $a" >&2; usage >&2; exit 2 ;;
    *) if [ -n "$out" ]; then echo "build-fmu: one OUT_DIR only" >&2; exit 2; fi; out="$a" ;;
  esac
done
if [ "$(uname -s)" != Linux ] || [ "$(uname -m)" != x86_64 ]; then
  echo "build-fmu: this script packages Linux x86-64 binaries; this is $(uname -s) $(uname -m)" >&2
  exit 2
fi
target_dir="${CARGO_TARGET_DIR:-$PWD/target}"
if [ "$portable" = 1 ]; then
  target_dir="$target_dir/portable"
  export CARGO_TARGET_DIR="$target_dir"
  # RUSTFLAGS replaces .cargo/config.toml's target-cpu=x86-64-v3.
  export RUSTFLAGS="-C target-cpu=x86-64"
fi
out="${out:-$PWD/target/fmu}"
if [ "$prebuilt" = 0 ]; then
  echo "build-fmu: building the FMU library (cargo build --release -p crawler-fmu$( [ "$portable" = 1 ] && echo ', portable x86-64' ))..." >&2
  "${CARGO:-cargo}" build --release -p crawler-fmu
fi
lib="$target_dir/release/libcrawler_fmu.so"
tool="$target_dir/release/crawler-fmu"
how="CARGO_TARGET_DIR=$target_dir cargo build --release -p crawler-fmu"
if [ "$portable" = 1 ]; then how="RUSTFLAGS=\"-C target-cpu=x86-64\" $how"; fi
for f in "$lib" "$tool"; do
  if [ ! -f "$f" ]; then
    echo "build-fmu: $f is missing: build it with \`$how\`, or run this script without --prebuilt" >&2
    exit 1
  fi
done
# `cargo test` links the shared library into release/deps/ without copying it to release/: a
# library there that differs from it is older than the last build (packaging it would ship old code)
built="$target_dir/release/deps/libcrawler_fmu.so"
if [ -f "$built" ] && ! cmp -s "$lib" "$built"; then
  echo "build-fmu: $lib is older than $built (a later cargo test build): build it with \`$how\`, or run this script without --prebuilt" >&2
  exit 1
fi

mkdir -p "$out"
stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
pack() { # version platform file
  local dir="$stage/fmi$1"
  mkdir -p "$dir/binaries/$2"
  "$tool" files --fmi "$1" --out "$dir"
  cp "$lib" "$dir/binaries/$2/crawler_physics.so"
  # Written beside the target and renamed when complete: a failed build never leaves a
  # truncated .fmu (nor truncates an existing one).
  (cd "$dir" && python3 -m zipfile -c "$out/.$3.partial" modelDescription.xml binaries documentation)
  mv -f "$out/.$3.partial" "$out/$3"
  echo "build-fmu: wrote $out/$3 (FMI $1.0, binaries/$2/crawler_physics.so)" >&2
}
pack 2 linux64 crawler_physics.fmu
pack 3 x86_64-linux crawler_plant_fmi3.fmu
