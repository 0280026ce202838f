#!/usr/bin/env bash
# Installs everything the tests need beyond cargo, in one step (idempotent: it installs only what
# is missing). Run it once before `cargo test --release --workspace`; .ci/run calls it.
#   - Debian packages (scripts/setup-debian.sh): libtbb12 for the ecos FMU importer;
#   - Slurm and MUNGE (scripts/setup-slurm.sh) for the sweep's Slurm test;
#   - the Python venv .venv with the pinned packages of requirements*.txt, and the Rerun viewer
#     (scripts/setup-python.sh --viewer).
# The Debian steps need root; as another user they call sudo, and only when a package is missing.
# No test installs anything itself: a test whose prerequisite is missing fails and names this script.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup-debian.sh
scripts/setup-slurm.sh
scripts/setup-python.sh --viewer
echo "setup: done (Debian packages, Slurm, .venv)" >&2
