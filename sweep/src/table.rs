//! The sweep's results as one table (one row per point, in plan order) and its Parquet file.
//!
//! The file is deterministic: rows in plan order, no timestamps, no host names; the only column
//! that differs between two runs of the same plan is `wall_time` (seconds spent on the point).
//! Column units are in each field's metadata (`unit`), the plan's name, the result format and
//! the code fingerprint in the file's key-value metadata.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use arrow_array::{
    ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray, UInt64Array,
};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;

use crate::plan::{column_type, ColumnType, Plan};
use crate::point::{Point, CODE, FORMAT};
use crate::record::{finite, Metrics, PlantResult, Record};
use crawler_facts::Metric;

enum Data {
    F64(Vec<Option<f64>>),
    I64(Vec<Option<i64>>),
    U64(Vec<Option<u64>>),
    Text(Vec<Option<String>>),
    Bool(Vec<Option<bool>>),
}

struct Column {
    name: String,
    unit: &'static str,
    doc: String,
    data: Data,
}

impl Column {
    fn array(self) -> (Field, ArrayRef) {
        let (dt, arr): (DataType, ArrayRef) = match self.data {
            Data::F64(v) => (DataType::Float64, Arc::new(Float64Array::from(v))),
            Data::I64(v) => (DataType::Int64, Arc::new(Int64Array::from(v))),
            Data::U64(v) => (DataType::UInt64, Arc::new(UInt64Array::from(v))),
            Data::Text(v) => (DataType::Utf8, Arc::new(StringArray::from(v))),
            Data::Bool(v) => (DataType::Boolean, Arc::new(BooleanArray::from(v))),
        };
        let mut md = HashMap::new();
        md.insert("unit".to_string(), self.unit.to_string());
        md.insert("doc".to_string(), self.doc);
        (Field::new(self.name, dt, true).with_metadata(md), arr)
    }
}

/// The difference of a model's value from the plant's: relative (`pred / plant - 1`) for the
/// physical metrics, absolute (`pred - plant`) for shares. `floor` keeps a relative error finite
/// where the plant's value vanishes (the speed at eps = 0): the denominator is at least `floor`.
pub fn model_error(
    metric: Metric,
    pred: Option<f64>,
    plant: Option<f64>,
    floor: f64,
) -> Option<f64> {
    let (p, q) = (pred?, plant?);
    if metric.info().share {
        return Some(p - q);
    }
    if p == q {
        return Some(0.0);
    }
    let den = q.abs().max(floor);
    (den > 0.0).then(|| (p - q) / den).filter(|e| e.is_finite())
}

/// The scales of a point: the body's oscillation speed `u_c omega = f0 omega / (k A_c E)` (m/s)
/// and the power `f0 u_c omega` per wavelength times the wavelengths on the body (W).
fn scales(point: &Point) -> (f64, f64) {
    let s = &point.scenario;
    let w = s.wave;
    let v = w.f0 * w.omega / (w.k * s.plant.body.stiffness());
    let waves = (w.k * s.plant.length / std::f64::consts::TAU)
        .round()
        .max(1.0);
    (v, w.f0 * v * waves)
}

/// The share of a point's scale below which a value counts as zero ([`error_floor`]; the column
/// docs quote it).
pub const FLOOR_SHARE: f64 = 1e-6;

/// Relative agreement of the N and 2N runs below which the difference is round-off, not an
/// estimate ([`conv_error`]).
pub const QUANTISED_AGREEMENT: f64 = 1e-9;

/// The floor of relative errors ([`model_error`], [`conv_error`]) for `metric` at `point`:
/// [`FLOOR_SHARE`] of the point's speed scale for the speed, of its power scale for the power and
/// of their ratio for the mileage. Values below it are zero up to round-off or solver tolerance
/// (without dry friction V = 0; a body at rest has V = 0 and P = 0); none for the other metrics.
pub fn error_floor(metric: Metric, point: &Point) -> f64 {
    let (v, p) = scales(point);
    match metric {
        Metric::Velocity => FLOOR_SHARE * v,
        Metric::Power => FLOOR_SHARE * p,
        Metric::Mileage if p > 0.0 => FLOOR_SHARE * v / p,
        _ => 0.0,
    }
}

/// Why a convergence estimate is withheld ([`conv_estimate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Untrusted {
    /// The N and 2N runs agree to round-off ([`QUANTISED_AGREEMENT`]) on a value above the floor:
    /// where the wave moves exactly one cell per step (Courant number `1 / alpha` above
    /// `alpha = 1.1`, and Courant 1 at `alpha = 1`) the speed comes in steps of
    /// `eps c_d / (c_v 2N)`, so both runs can land on the same step while each is off by far more
    /// (alpha 1.7, eps 0.05, f0 0.15 N, k 4 pi, 256 cells: 1e-13 against 1.5e-3).
    Quantised,
    /// A stick statistic at a Courant number known to bias it ([`Scenario::caveats`]): both runs
    /// share the bias, so their difference does not show it.
    ///
    /// [`Scenario::caveats`]: crawler_physics::scenario::Scenario::caveats
    BiasedCourant,
}

/// The estimated discretisation error of the reported plant value of metric `name` at `point`
/// ([`conv_estimate`]), `None` where it is withheld as untrusted or there is nothing to compare.
pub fn conv_error(result: &PlantResult, name: Metric, point: &Point) -> Option<f64> {
    conv_estimate(result, name, point)?.ok()
}

/// The estimated discretisation error of the reported plant value of metric `name` at `point`:
/// `|fine - coarse| / max(|fine|, floor)` ([`error_floor`]); for shares (the stuck fraction, the
/// friction selection, episodes) the absolute difference. It bounds the finer run's error when
/// the scheme converges at first order or better (at second order it is three times that error,
/// tested). `None` without a coarse run or a value; `Some(Err(why))` where the difference is
/// known not to estimate the error ([`Untrusted`]).
pub fn conv_estimate(
    result: &PlantResult,
    name: Metric,
    point: &Point,
) -> Option<Result<f64, Untrusted>> {
    let coarse = result.coarse.as_ref()?;
    let f = comparable(name, &result.run.metrics, point)?;
    let c = comparable(name, &coarse.metrics, point)?;
    let d = (f - c).abs();
    if name.info().share {
        if !point.scenario.caveats().is_empty() {
            return Some(Err(Untrusted::BiasedCourant));
        }
        return Some(Ok(d));
    }
    let floor = error_floor(name, point);
    if f.abs() > floor && d <= QUANTISED_AGREEMENT * f.abs() {
        return Some(Err(Untrusted::Quantised));
    }
    if d == 0.0 {
        return Some(Ok(d));
    }
    let den = f.abs().max(floor);
    (den > 0.0).then(|| d / den).and_then(finite).map(Ok)
}

/// The value of `metric` in `m` that a model is compared on: the mileage `|V| / P` only where
/// the power is above round-off (a body at rest has no mileage: 0 / 0).
pub fn comparable(metric: Metric, m: &Metrics, point: &Point) -> Option<f64> {
    let v = m.get(metric)?;
    if metric == Metric::Mileage && m.get(Metric::Power)?.abs() <= error_floor(Metric::Power, point)
    {
        return None;
    }
    Some(v)
}

/// The model's error for `metric` at `point` ([`model_error`] of the [`comparable`] values).
pub fn point_error(metric: Metric, point: &Point, model: &Metrics, plant: &Metrics) -> Option<f64> {
    model_error(
        metric,
        comparable(metric, model, point),
        comparable(metric, plant, point),
        error_floor(metric, point),
    )
}

/// The results of `points` (plan order) with their `records` (same order) as one batch.
pub fn batch(plan: &Plan, points: &[Point], records: &[Record]) -> anyhow::Result<RecordBatch> {
    assert_eq!(points.len(), records.len());
    let mut cols: Vec<Column> = Vec::new();
    let f64col = |name: String,
                  unit: &'static str,
                  doc: String,
                  f: &dyn Fn(&Point, &Record) -> Option<f64>| Column {
        name,
        unit,
        doc,
        data: Data::F64(points.iter().zip(records).map(|(p, r)| f(p, r)).collect()),
    };
    cols.push(Column {
        name: "index".into(),
        unit: "1",
        doc: "position of the point in the plan (row-major over the axes, the last fastest)".into(),
        data: Data::U64(points.iter().map(|p| Some(p.index as u64)).collect()),
    });
    cols.push(Column {
        name: "point_id".into(),
        unit: "",
        doc: "SHA-256 of the resolved scenario, what is evaluated, the result format and the code fingerprint".into(),
        data: Data::Text(points.iter().map(|p| Some(p.id.clone())).collect()),
    });
    // axis columns, as given in the plan
    for a in &plan.axes {
        let types =
            column_type(&a.keys, &a.values).map_err(|(k, why)| anyhow::anyhow!("{k}: {why}"))?;
        for (key, t) in a.keys.iter().zip(types) {
            let pos = points
                .iter()
                .map(|p| {
                    p.assignments
                        .iter()
                        .filter(|(k, _)| k == key)
                        .map(|(_, v)| v)
                        .next()
                        .expect("every point has every axis")
                })
                .collect::<Vec<_>>();
            let data = match t {
                ColumnType::Float => Data::F64(
                    pos.iter()
                        .map(|v| v.as_float().or(v.as_integer().map(|i| i as f64)))
                        .collect(),
                ),
                ColumnType::Int => Data::I64(pos.iter().map(|v| v.as_integer()).collect()),
                ColumnType::Text => {
                    Data::Text(pos.iter().map(|v| v.as_str().map(str::to_string)).collect())
                }
                ColumnType::Bool => Data::Bool(pos.iter().map(|v| v.as_bool()).collect()),
            };
            cols.push(Column {
                name: key.clone(),
                unit: "",
                doc: format!("axis value of scenario key {key}, as given in the plan"),
                data,
            });
        }
    }
    // the resolved inputs
    type Input = (&'static str, &'static str, &'static str, fn(&Point) -> f64);
    let inputs: [Input; 18] = [
        ("eps", "1", "dry-friction coefficient", |p| {
            p.scenario.plant.friction.eps
        }),
        ("n_f", "1", "friction asymmetry n_F", |p| {
            p.scenario.plant.friction.n_f
        }),
        ("f0", "N", "wave amplitude", |p| p.scenario.wave.f0),
        ("k", "rad/m", "wave number", |p| p.scenario.wave.k),
        ("omega", "rad/s", "angular frequency", |p| {
            p.scenario.wave.omega
        }),
        ("alpha", "1", "omega / omega_n", |p| p.scenario.alpha()),
        (
            "zeta",
            "1",
            "paper's zeta = c_v / (k sqrt(rho A_c E))",
            |p| crawler_models::OperatingPoint::of(&p.scenario).zeta(),
        ),
        ("pi_r", "1", "paper's pi_r = c_d / (f0 k)", |p| {
            crawler_models::OperatingPoint::of(&p.scenario).pi_r()
        }),
        ("length", "m", "body length L", |p| p.scenario.plant.length),
        ("area", "m^2", "cross-section A_c", |p| {
            p.scenario.plant.body.area
        }),
        ("density", "kg/m", "linear density rho", |p| {
            p.scenario.plant.body.density
        }),
        ("youngs_modulus", "Pa", "Young's modulus E", |p| {
            p.scenario.plant.body.youngs_modulus
        }),
        ("viscous", "N s/m^2", "viscous coefficient c_v", |p| {
            p.scenario.plant.friction.viscous
        }),
        ("dry", "N/m", "normal load c_d", |p| {
            p.scenario.plant.friction.dry
        }),
        ("courant", "1", "upper bound of c dt / dx", |p| {
            p.scenario.plant.numerics.courant
        }),
        (
            "step",
            "s",
            "communication step H (the requested one rounded to whole internal steps)",
            |p| {
                p.scenario
                    .plant
                    .discretisation()
                    .map_or(f64::NAN, |d| d.step)
            },
        ),
        ("t_end", "s", "end time", |p| p.scenario.t_end),
        ("settle", "s", "transient excluded from the metrics", |p| {
            p.scenario.plant.numerics.settle
        }),
    ];
    for (name, unit, doc, f) in inputs {
        cols.push(f64col(name.into(), unit, doc.into(), &|p, _| {
            let x = f(p);
            x.is_finite().then_some(x)
        }));
    }
    cols.push(Column {
        name: "cells".into(),
        unit: "1",
        doc: "the point's number of cells N (numerics.cells)".into(),
        data: Data::I64(
            points
                .iter()
                .map(|p| Some(p.scenario.plant.numerics.cells as i64))
                .collect(),
        ),
    });
    cols.push(Column {
        name: "scenario".into(),
        unit: "",
        doc: "the point's resolved scenario file (TOML): every input".into(),
        data: Data::Text(points.iter().map(|p| Some(p.toml.clone())).collect()),
    });

    let e = &plan.evaluate;
    if e.plant {
        cols.push(Column {
            name: "plant.cells".into(),
            unit: "1",
            doc: "cells of the reported plant run (2N with the convergence check)".into(),
            data: Data::U64(
                records
                    .iter()
                    .map(|r| r.plant.as_ref().map(|p| p.run.cells))
                    .collect(),
            ),
        });
        cols.push(f64col(
            "plant.dt".into(),
            "s",
            "internal step of the reported run".into(),
            &|_, r| r.plant.as_ref().map(|p| p.run.dt),
        ));
        cols.push(Column {
            name: "plant.steps".into(),
            unit: "1",
            doc: "internal steps of the reported run".into(),
            data: Data::U64(
                records
                    .iter()
                    .map(|r| r.plant.as_ref().map(|p| p.run.steps))
                    .collect(),
            ),
        });
        cols.push(f64col(
            "plant.window_periods".into(),
            "1",
            "forcing periods in the averaging window".into(),
            &|_, r| r.plant.as_ref().map(|p| p.run.window_periods),
        ));
        cols.push(f64col(
            "plant.momentum_residual".into(),
            "1",
            "relative residual of the discrete momentum balance".into(),
            &|_, r| r.plant.as_ref().and_then(|p| p.run.momentum_residual),
        ));
        cols.push(Column {
            name: "plant.state_digest".into(),
            unit: "",
            doc: "CRC-32 of the final state of the reported run".into(),
            data: Data::Text(
                records
                    .iter()
                    .map(|r| r.plant.as_ref().map(|p| p.run.state_digest.clone()))
                    .collect(),
            ),
        });
        for &m in &plan.metrics {
            cols.push(f64col(
                format!("plant.{m}"),
                m.unit(),
                format!("plant's {}, {}", m.info().label, m.info().doc),
                &|_, r| r.plant.as_ref().and_then(|p| p.run.metrics.get(m)),
            ));
            if e.convergence {
                cols.push(f64col(
                    format!("plant.{m}.conv_error"),
                    "1",
                    format!(
                        "estimated discretisation error of plant.{m}: |value(2N) - value(N)|{}",
                        if m.info().share {
                            "; null where numerics.courant is known to bias the stick statistics (the two runs share the bias)".to_string()
                        } else {
                            format!(" / max(|value(2N)|, {FLOOR_SHARE:e} of the point's scale); null where the two agree to {QUANTISED_AGREEMENT:e} (where the wave moves one cell per step the speed is quantised, so N and 2N can agree exactly while both are off)")
                        }
                    ),
                    &|p, r| r.plant.as_ref().and_then(|pr| conv_error(pr, m, p)),
                ));
            }
        }
    }
    for (mi, model) in e.models.iter().enumerate() {
        fn pick(r: &Record, mi: usize) -> Option<&crate::record::ModelResult> {
            r.models.get(mi)
        }
        cols.push(Column {
            name: format!("{model}.valid"),
            unit: "",
            doc: format!("whether the {model} model's formulas apply"),
            data: Data::Bool(
                records
                    .iter()
                    .map(|r| pick(r, mi).map(|x| x.valid))
                    .collect(),
            ),
        });
        cols.push(Column {
            name: format!("{model}.reason"),
            unit: "",
            doc: format!("why the {model} model does not apply"),
            data: Data::Text(
                records
                    .iter()
                    .map(|r| pick(r, mi).and_then(|x| x.reason.clone()))
                    .collect(),
            ),
        });
        for &m in &plan.metrics {
            cols.push(f64col(
                format!("{model}.{m}"),
                m.unit(),
                format!("{model} model's {m}"),
                &|_, r| pick(r, mi).and_then(|x| x.metrics.get(m)),
            ));
            if e.plant {
                cols.push(f64col(
                    format!("{model}.{m}.error"),
                    "1",
                    if m.info().share {
                        format!("{model}.{m} - plant.{m}")
                    } else {
                        format!(
                            "{model}.{m} / plant.{m} - 1 (the denominator at least {FLOOR_SHARE:e} of the point's scale; null where undefined)"
                        )
                    },
                    &|p, r| {
                        let plant = r.plant.as_ref()?;
                        point_error(m, p, &pick(r, mi)?.metrics, &plant.run.metrics)
                    },
                ));
            }
        }
    }
    if e.policy.is_some() {
        cols.push(Column {
            name: "policy.name".into(),
            unit: "",
            doc: "the policy".into(),
            data: Data::Text(
                records
                    .iter()
                    .map(|r| r.policy.as_ref().map(|p| p.policy.clone()))
                    .collect(),
            ),
        });
        cols.push(Column {
            name: "policy.steady".into(),
            unit: "",
            doc: "true: steady window; false: run averages of a time-varying policy".into(),
            data: Data::Bool(
                records
                    .iter()
                    .map(|r| r.policy.as_ref().map(|p| p.steady))
                    .collect(),
            ),
        });
        for (i, (n, u)) in [("f0", "N"), ("k", "rad/m"), ("omega", "rad/s")]
            .into_iter()
            .enumerate()
        {
            cols.push(f64col(
                format!("policy.{n}"),
                u,
                format!("{n} of the last wave the policy commanded"),
                &|_, r| r.policy.as_ref().and_then(|p| p.wave).map(|w| w[i]),
            ));
        }
        for &m in &plan.metrics {
            cols.push(f64col(
                format!("policy.{m}"),
                m.unit(),
                format!("plant's {m} under the policy"),
                &|_, r| r.policy.as_ref().and_then(|p| p.run.metrics.get(m)),
            ));
        }
    }
    cols.push(Column {
        name: "error".into(),
        unit: "",
        doc: "why the point's evaluation failed (null: it did not)".into(),
        data: Data::Text(records.iter().map(|r| r.error.clone()).collect()),
    });
    cols.push(f64col(
        "wall_time".into(),
        "s",
        "wall time of the point's evaluation (the only column that differs between runs)".into(),
        &|_, r| Some(r.wall_time),
    ));

    let (fields, arrays): (Vec<Field>, Vec<ArrayRef>) = cols.into_iter().map(Column::array).unzip();
    let schema = Arc::new(Schema::new(fields));
    Ok(RecordBatch::try_new(schema, arrays)?)
}

/// The file's key-value metadata: plan, format, code fingerprint (no time, no host).
pub fn metadata(plan: &Plan) -> Vec<KeyValue> {
    vec![
        KeyValue::new("crawler.sweep.plan".into(), plan.name.clone()),
        KeyValue::new("crawler.sweep.description".into(), plan.description.clone()),
        KeyValue::new("crawler.sweep.format".into(), FORMAT.to_string()),
        KeyValue::new("crawler.sweep.code".into(), CODE.to_string()),
        KeyValue::new(
            "crawler.sweep.row_order".into(),
            "plan order (column index)".to_string(),
        ),
    ]
}

/// Writes the batch as Parquet to `path`, atomically: a temporary file next to it, renamed over
/// it when complete (an existing file is never truncated by a failed write).
pub fn write_parquet(plan: &Plan, batch: &RecordBatch, path: &Path) -> anyhow::Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let tmp = dir.join(format!(
        ".{}.{}.tmp",
        path.file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default(),
        std::process::id()
    ));
    let props = WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .set_key_value_metadata(Some(metadata(plan)))
        .build();
    let write = || -> anyhow::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut w = ArrowWriter::try_new(file, batch.schema(), Some(props))?;
        w.write(batch)?;
        w.close()?;
        std::fs::rename(&tmp, path)?;
        Ok(())
    };
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        anyhow::anyhow!("cannot write {}: {e}", path.display())
    })
}
