"""The soft peristaltic crawler of Gusty et al. with exact stick-slip friction, in Python.

The package binds the libraries the project's programs use (no second implementation):

- :class:`Scenario`: scenario files, dicts or keyword overrides, validated by the programs'
  parser (an input that is not allowed raises :class:`InvalidInput` naming the field, the value
  and what is allowed);
- :class:`Plant` and :func:`simulate`: the plant run by the physics crate's execution loop, with
  its fields as NumPy arrays, its state and its :class:`Report` (the same bits as
  ``crawler-plant simulate --json``);
- :func:`predict` (the paper's and the improved model), :func:`optimize` (the constrained optimum,
  verified or certified on the plant), :func:`sweep` (a plan's table as a pyarrow Table);
- :func:`run` (a policy, Python or registered, in closed loop in process) and :func:`connect`
  (a policy controlling a co-simulated run);
- ``softcrawler.env``: the Gymnasium environment ``SoftCrawler-v0`` and its vector version.

Units are SI throughout. The GIL is released while Rust computes.
"""

from __future__ import annotations

from . import _native
from .client import Connection, connect
from .errors import InvalidInput, RunError, SoftCrawlerError
from .models import Optimization, Prediction, optimize, predict
from .plant import Observation, Plant, State, simulate
from .policy import EnvPolicy, Run, Wave, registered, run
from .report import Report
from .scenario import Scenario
from .sweep import sweep

__version__: str = _native.__version__

__all__ = [
    "Connection", "EnvPolicy", "InvalidInput", "Observation", "Optimization", "Plant",
    "Prediction", "Report", "Run", "RunError", "Scenario", "SoftCrawlerError", "State", "Wave",
    "connect", "optimize", "predict", "registered", "run", "simulate", "sweep",
]
