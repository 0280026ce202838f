"""sweep returns the rows `crawler sweep` writes (the same library)."""

from __future__ import annotations

import subprocess

import pyarrow.parquet as pq

import softcrawler
from conftest import ROOT, program

PLAN = """name = "pytiny"
scenario = "{base}"
[set]
numerics.cells = 32
numerics.settle = 1.5
numerics.t_end = 3.0
[[axes]]
key = "friction.eps"
values = [0.0, 0.5]
[[axes]]
key = "actuation.alpha"
values = [0.6, 1.2]
[evaluate]
plant = true
models = ["paper", "improved"]
"""


def test_a_sweep_gives_the_rows_of_crawler_sweep(tmp_path):
    plan = tmp_path / "pytiny.toml"
    plan.write_text(PLAN.format(base=ROOT / "scenarios/paper.toml"))
    out = subprocess.run([program("crawler-sweep"), str(plan), "--out", "cli.parquet", "--store",
                          "cli-store", "--no-figures", "--no-progress"],
                         cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    cli = pq.read_table(tmp_path / "cli.parquet")
    table = softcrawler.sweep(plan, out=tmp_path / "py.parquet", store=tmp_path / "py-store", jobs=2)
    assert table.num_rows == 4
    assert table.schema == cli.schema
    # every column but the measured wall-clock time of a point is the same, bit for bit
    rows, cli_rows = table.to_pydict(), cli.to_pydict()
    assert all(t > 0 for t in rows.pop("wall_time") + cli_rows.pop("wall_time"))
    assert rows == cli_rows
    assert table.schema.metadata == cli.schema.metadata
    # a second call finds every point in the store and runs none (the stored rows, times and all)
    again = softcrawler.sweep(plan, out=tmp_path / "py2.parquet", store=tmp_path / "py-store")
    assert again.to_pydict() == table.to_pydict()
