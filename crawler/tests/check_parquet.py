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
meta = {k.decode(): v.decode() for k, v in (pf.metadata.metadata or {}).items()}
assert meta.get("crawler.sweep.format") == "2", meta.keys()
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
    # the plant's steady-state identity, up to the window's change of momentum rho dV / T_w
    # (short settle times here); the scheme's discrete momentum balance itself holds to round-off
    assert abs(v - eps * dry * (n_f - s) / visc) <= 1e-4 * abs(v), (i, v)
    assert d["plant.momentum_residual"][i] < 1e-10, d["plant.momentum_residual"][i]
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
    # the relative error's floors: 1e-6 of the speed scale f0 omega / (k A_c E), of the power
    # scale f0 times that times the wavelengths on the body, and of their ratio
    v_scale = d["f0"][i] * d["omega"][i] / (d["k"][i] * d["area"][i] * d["youngs_modulus"][i])
    waves = max(round(d["k"][i] * d["length"][i] / (2 * math.pi)), 1)
    p_scale = d["f0"][i] * v_scale * waves
    floor = {"velocity": 1e-6 * v_scale, "power": 1e-6 * p_scale, "mileage": 1e-6 * v_scale / p_scale}
    for model in ("paper", "improved"):
        for m in ("velocity", "power", "mileage", "max_stress"):
            p, q, e = d[f"{model}.{m}"][i], d[f"plant.{m}"][i], d[f"{model}.{m}.error"][i]
            if m == "mileage":
                if d[f"{model}.power"][i] is None or abs(d[f"{model}.power"][i]) <= floor["power"]:
                    p = None
                if abs(d["plant.power"][i]) <= floor["power"]:
                    q = None
            if p is None or q is None:
                assert e is None
                continue
            want = 0.0 if p == q else (p - q) / max(abs(q), floor.get(m, 0.0))
            assert abs(e - want) <= 1e-12 * max(1.0, abs(want)), (model, m, i, e, want)
            checked += 1
        e, sf = d[f"{model}.stuck_fraction.error"][i], d[f"{model}.stuck_fraction"][i]
        assert e == (None if sf is None else sf - d["plant.stuck_fraction"][i]), (model, i, e)
print(f"ok: {rows} rows, {len(t.schema)} columns, {checked} errors checked")
