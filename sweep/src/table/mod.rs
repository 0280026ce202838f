//! The sweep's results as one table (one row per point, in plan order) and its Parquet file.
//!
//! The file is deterministic: rows in plan order, no timestamps, no host names; the only column
//! that differs between two runs of the same plan is `wall_time` (seconds spent on the point).
//! Column units are in each field's metadata (`unit`), the plan's name, the result format and
//! the code fingerprint in the file's key-value metadata.

use std::path::Path;

use arrow_array::RecordBatch;
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;

use crate::plan::Plan;
use crate::point::{Point, CODE, FORMAT};
use crate::record::{finite, Metrics, PlantResult};
use crawler_facts::Metric;

mod columns;

pub use columns::batch;

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
