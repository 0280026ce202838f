#!/usr/bin/env bash
# Creates .venv with the pinned Python packages of requirements.txt and requirements-peers.txt
# (idempotent).
# With --viewer it also installs the Rerun viewer (requirements-viewer.txt).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
# (find_spec, not import: ecospy's import loads its native library, which needs libtbb12.)
if ! .venv/bin/python -c 'import importlib.util as u, sys; sys.exit(any(u.find_spec(m) is None for m in ("zenoh", "msgpack", "numpy", "pyarrow", "fmpy", "fmu_manipulation_toolbox", "ecospy", "libcosimpy", "pythonfmu", "mujoco", "elastica", "numba")))' 2>/dev/null || [ requirements.txt -nt .venv/.installed ] || [ requirements-peers.txt -nt .venv/.installed ]; then
  .venv/bin/pip install --quiet --disable-pip-version-check -r requirements.txt -r requirements-peers.txt
  touch .venv/.installed
fi
if [ "${1:-}" = "--viewer" ] && [ ! -x .venv/bin/rerun ]; then
  .venv/bin/pip install --quiet --disable-pip-version-check -r requirements-viewer.txt
fi
