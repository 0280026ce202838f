"""Sweeps (``crawler_sweep``), as ``crawler sweep PLAN`` runs them on this machine's cores."""

from __future__ import annotations

import os
from typing import Any

from . import _native
from .errors import invalid, whole


def sweep(plan: str | os.PathLike[str], *, out: str | os.PathLike[str] | None = None,
          store: str | os.PathLike[str] | None = None, jobs: int | None = None,
          retry_failed: bool = False, root: str | os.PathLike[str] = "out") -> Any:
    """Runs the sweep plan (TOML) on ``jobs`` threads (default: all cores) and returns its table
    as a ``pyarrow.Table``: the rows ``crawler sweep`` writes (the same library, store and
    Parquet file; points already in the store are not run again). Defaults as ``crawler
    sweep``'s: ``out/sweeps/<plan>.parquet`` and the store ``out/sweep-store``. Needs pyarrow.
    Ctrl-C finishes the running points, keeps them and raises ``KeyboardInterrupt``."""
    import pyarrow.parquet as pq

    if not isinstance(plan, (str, os.PathLike)):
        raise invalid("plan", plan, "a sweep plan file's path")
    if jobs is not None:
        jobs = whole("jobs", jobs, 1)
    path = _native.sweep(os.fspath(plan), None if out is None else os.fspath(out),
                         None if store is None else os.fspath(store), jobs, retry_failed,
                         os.fspath(root))
    return pq.read_table(path)
