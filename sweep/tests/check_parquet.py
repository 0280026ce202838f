"""Reads a sweep's Parquet file with pyarrow (and pandas-free numpy) and checks it against
formulas computed here, independently of the Rust code: the models' error columns, the plant's
steady-state identity V = eps c_d (n_F - <s>) / c_v, and the paper model's validity condition.

Usage: check_parquet.py FILE ROWS
"""
import math
import sys

import pyarrow.parquet as pq

path, rows = sys.argv[1], int(sys.argv[2])
pf = pq.ParquetFile(path)
t = pf.read()
meta = {k.decode(): v.decode() for k, v in (pf.schema_arrow.metadata or {}).items()}
assert meta.get("crawler.sweep.format") == "1", meta.keys()
assert "crawler.sweep.code" in meta
assert t.num_rows == rows, (t.num_rows, rows)
d = t.to_pydict()
assert d["index"] == list(range(rows)), d["index"]
assert len(set(d["point_id"])) == rows
assert all(len(i) == 64 for i in d["point_id"])
units = {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in t.schema}
assert units["plant.velocity"] == "m/s" and units["plant.power"] == "W", units
assert units["paper.max_stress"] == "Pa" and units["wall_time"] == "s", units
assert t.schema.field("plant.cells").type == "uint64"

checked = 0
for i in range(rows):
    assert d["error"][i] is None, d["error"][i]
    eps, dry, visc, n_f = d["eps"][i], d["dry"][i], d["viscous"][i], d["n_f"][i]
    v = d["plant.velocity"][i]
    s = d["plant.mean_friction_selection"][i]
    # the plant's steady-state identity (exact in the scheme)
    assert abs(v - eps * dry * (n_f - s) / visc) <= 1e-9 * max(abs(v), 1e-12), (i, v)
    # reported run at 2N
    assert d["plant.cells"][i] == 2 * d["cells"][i]
    # the paper's validity: eps C0 / (R0 alpha) <= 1 with C0 = pi_r n_F / zeta
    a, z, pr = d["alpha"][i], d["zeta"][i], d["pi_r"][i]
    r0 = 1 / math.sqrt((a * a - 1) ** 2 + (z * a) ** 2)
    valid = eps * pr * n_f / z / (r0 * a) <= 1
    assert d["paper.valid"][i] == valid, (i, d["paper.valid"][i], valid)
    if valid:
        # eq. (31)
        g = math.asin(eps * pr * n_f / z / (r0 * a))
        vp = eps * dry / visc * (n_f - 2 * g / math.pi)
        assert abs(d["paper.velocity"][i] - vp) <= 1e-12 * abs(vp) + 1e-300, (i, vp)
    else:
        assert d["paper.velocity"][i] is None and d["paper.reason"][i]
    for model in ("paper", "improved"):
        for m in ("velocity", "power", "mileage", "max_stress"):
            p, q, e = d[f"{model}.{m}"][i], d[f"plant.{m}"][i], d[f"{model}.{m}.error"][i]
            if p is None:
                assert e is None
                continue
            want = 0.0 if p == q else (p - q) / abs(q)
            assert abs(e - want) <= 1e-12 * max(1.0, abs(want)), (model, m, i, e, want)
            checked += 1
        e = d[f"{model}.stuck_fraction.error"][i]
        assert e == d[f"{model}.stuck_fraction"][i] - d["plant.stuck_fraction"][i]
print(f"ok: {rows} rows, {len(t.schema)} columns, {checked} errors checked")
