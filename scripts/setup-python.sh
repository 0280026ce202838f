#!/usr/bin/env bash
# Creates .venv with the pinned Python packages of requirements.txt and requirements-peers.txt
# (idempotent).
# With --package it also (re)installs the project's own package, softcrawler, from the current
# sources (`pip install ./python`: maturin builds it with cargo in the workspace's target dir;
# docs/python.md). tests/tests/python_package.rs calls it so.
# With --viewer it also installs the Rerun viewer (requirements-viewer.txt).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
# (find_spec, not import: ecospy's import loads its native library, which needs libtbb12.)
if ! .venv/bin/python -c 'import importlib.util as u, sys; sys.exit(any(u.find_spec(m) is None for m in ("zenoh", "msgpack", "numpy", "pyarrow", "fmpy", "fmu_manipulation_toolbox", "ecospy", "libcosimpy", "pythonfmu", "mujoco", "elastica", "numba", "gymnasium", "cma", "pytest", "maturin")))' 2>/dev/null || [ requirements.txt -nt .venv/.installed ] || [ requirements-peers.txt -nt .venv/.installed ]; then
  .venv/bin/pip install --quiet --disable-pip-version-check -r requirements.txt -r requirements-peers.txt
  touch .venv/.installed
fi
# The package: `pip install ./python`, with the venv's pinned maturin (no download) and the
# repository's cargo target dir, so the wheel's build reuses what `cargo build --release` compiled.
if [ "${1:-}" = "--package" ]; then
  PATH="$PWD/.venv/bin:$PATH" .venv/bin/pip install --quiet --disable-pip-version-check \
    --no-build-isolation --no-deps --force-reinstall ./python
fi
if [ "${1:-}" = "--viewer" ] && [ ! -x .venv/bin/rerun ]; then
  .venv/bin/pip install --quiet --disable-pip-version-check -r requirements-viewer.txt
fi
