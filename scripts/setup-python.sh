#!/usr/bin/env bash
# Creates .venv with the pinned Python packages of requirements.txt (idempotent).
# With --viewer it also installs the Rerun viewer (requirements-viewer.txt).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
if ! .venv/bin/python -c 'import zenoh, msgpack, numpy, pyarrow' 2>/dev/null || [ requirements.txt -nt .venv/.installed ]; then
  .venv/bin/pip install --quiet --disable-pip-version-check -r requirements.txt
  touch .venv/.installed
fi
if [ "${1:-}" = "--viewer" ] && [ ! -x .venv/bin/rerun ]; then
  .venv/bin/pip install --quiet --disable-pip-version-check -r requirements-viewer.txt
fi
