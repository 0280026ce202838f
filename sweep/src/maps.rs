//! The maps of a plan with `[figures]`: for each panel (a value of `rows` x a value of
//! `columns`) a grid over (`y`, `x`) of the models' errors against the plant, the plant's stuck
//! fraction and its convergence estimate. Shared by the PNG figures and the Rerun recording.

use std::collections::BTreeMap;

use crawler_facts::Metric;

use crate::plan::{MapFigures, Plan};
use crate::point::Point;
use crate::record::Record;
use crate::table::{conv_estimate, point_error};

/// The metrics a map shows (those of them the plan keeps).
pub const MAP_METRICS: [Metric; 4] = [
    Metric::Velocity,
    Metric::Power,
    Metric::Mileage,
    Metric::MaxStress,
];

/// A numeric axis of the map.
#[derive(Debug, Clone)]
pub struct MapAxis {
    /// The plan's key.
    pub key: String,
    /// Its values, in plan order.
    pub values: Vec<toml::Value>,
}

impl MapAxis {
    /// The values as numbers (`None` for a non-numeric value).
    pub fn numbers(&self) -> Vec<Option<f64>> {
        self.values
            .iter()
            .map(|v| v.as_float().or(v.as_integer().map(|i| i as f64)))
            .collect()
    }

    /// A short label of value `i` for panel titles, e.g. `k = 4 pi rad/m` or `f0 = 0.5 N`.
    pub fn label(&self, i: usize) -> String {
        let name = short_name(&self.key);
        let v = &self.values[i];
        match (
            v.as_float().or(v.as_integer().map(|i| i as f64)),
            name.as_str(),
        ) {
            (Some(k), "k") => {
                let m = k / std::f64::consts::PI;
                if (m - m.round()).abs() < 1e-9 {
                    format!("k = {} pi rad/m", m.round())
                } else {
                    format!("k = {k:.4} rad/m")
                }
            }
            (Some(x), n) => format!("{n} = {}{}", trim(x), unit_of(n)),
            (None, n) => format!("{n} = {v}"),
        }
    }
}

/// The last part of a dotted key.
pub fn short_name(key: &str) -> String {
    key.rsplit('.').next().unwrap_or(key).to_string()
}

fn trim(x: f64) -> String {
    let s = format!("{x:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

/// Units of the common scenario fields, for labels.
pub fn unit_of(name: &str) -> &'static str {
    match name {
        "f0" => " N",
        "omega" => " rad/s",
        "k" => " rad/m",
        "length" => " m",
        "t_end" | "settle" | "step" => " s",
        _ => "",
    }
}

/// A grid over (y, x) of one panel: `values[iy * nx + ix]`, `None` where undefined.
pub type Grid = Vec<Option<f64>>;

/// Everything the figures and the recording draw.
#[derive(Debug, Clone)]
pub struct Maps {
    /// Horizontal axis of each panel.
    pub x: MapAxis,
    /// Vertical axis of each panel.
    pub y: MapAxis,
    /// Axis along the rows of panels (one row without).
    pub rows: Option<MapAxis>,
    /// Axis along the columns of panels (one column without).
    pub columns: Option<MapAxis>,
    /// The models compared.
    pub models: Vec<String>,
    /// The metrics compared.
    pub metrics: Vec<Metric>,
    /// (model, metric) -> panel (row-major: row * ncols + col) -> model error (relative).
    pub errors: BTreeMap<(String, Metric), Vec<Grid>>,
    /// model -> panel -> 1 where the model's formulas apply, 0 where not.
    pub valid: BTreeMap<String, Vec<Grid>>,
    /// panel -> the plant's stuck fraction.
    pub stuck: Vec<Grid>,
    /// panel -> the largest estimated discretisation error of the plant over the metrics that have one.
    pub convergence: Vec<Grid>,
}

impl Maps {
    /// Rows of panels.
    pub fn nrows(&self) -> usize {
        self.rows.as_ref().map_or(1, |a| a.values.len())
    }

    /// Columns of panels.
    pub fn ncols(&self) -> usize {
        self.columns.as_ref().map_or(1, |a| a.values.len())
    }

    /// Points per panel.
    pub fn cells(&self) -> usize {
        self.x.values.len() * self.y.values.len()
    }

    /// The largest |error| over the metrics of `model` that have one; undefined where the
    /// model's formulas do not apply (or no metric has an error: a body at rest has no mileage).
    pub fn worst(&self, model: &str) -> Vec<Grid> {
        let n = self.nrows() * self.ncols();
        (0..n)
            .map(|panel| {
                (0..self.cells())
                    .map(|i| {
                        if self.valid[model][panel][i] != Some(1.0) {
                            return None;
                        }
                        self.metrics
                            .iter()
                            .filter_map(|&m| self.errors[&(model.to_string(), m)][panel][i])
                            .map(f64::abs)
                            .reduce(f64::max)
                    })
                    .collect()
            })
            .collect()
    }

    /// Builds the maps of `fig` from the plan's points and records (plan order).
    pub fn build(
        plan: &Plan,
        fig: &MapFigures,
        points: &[Point],
        records: &[Record],
    ) -> anyhow::Result<Self> {
        let (x, y, rows, columns) = map_axes(plan, fig)?;
        let models = plan.evaluate.models.clone();
        let metrics: Vec<Metric> = MAP_METRICS
            .into_iter()
            .filter(|m| plan.metrics.contains(m))
            .collect();
        let (nx, ny) = (x.values.len(), y.values.len());
        let nr = rows.as_ref().map_or(1, |a| a.values.len());
        let nc = columns.as_ref().map_or(1, |a| a.values.len());
        let empty = || vec![vec![None; nx * ny]; nr * nc];
        let mut errors: BTreeMap<(String, Metric), Vec<Grid>> = BTreeMap::new();
        for m in &models {
            for &k in &metrics {
                errors.insert((m.clone(), k), empty());
            }
        }
        let mut valid: BTreeMap<String, Vec<Grid>> =
            models.iter().map(|m| (m.clone(), empty())).collect();
        let mut stuck = empty();
        let mut convergence = empty();
        let pos = |a: &MapAxis, p: &Point| -> usize {
            let v = p
                .assignments
                .iter()
                .find(|(k, _)| *k == a.key)
                .map(|(_, v)| v)
                .expect("every point has every axis");
            a.values
                .iter()
                .position(|x| x == v)
                .expect("a value of the axis")
        };
        for (p, r) in points.iter().zip(records) {
            let ix = pos(&x, p);
            let iy = pos(&y, p);
            let ir = rows.as_ref().map_or(0, |a| pos(a, p));
            let ic = columns.as_ref().map_or(0, |a| pos(a, p));
            let panel = ir * nc + ic;
            let cell = iy * nx + ix;
            let Some(plant) = &r.plant else { continue };
            stuck[panel][cell] = plant.run.metrics.get(Metric::StuckFraction);
            // the largest estimate among the metrics that have one (a body at rest has no
            // mileage); none where any metric's estimate is untrusted (table::Untrusted)
            let estimates: Vec<_> = metrics
                .iter()
                .filter_map(|&m| conv_estimate(plant, m, p))
                .collect();
            convergence[panel][cell] = if estimates.iter().any(|e| e.is_err()) {
                None
            } else {
                estimates.into_iter().flatten().reduce(f64::max)
            };
            for (mi, model) in models.iter().enumerate() {
                let Some(mr) = r.models.get(mi) else { continue };
                valid.get_mut(model).expect("a model")[panel][cell] =
                    Some(if mr.valid { 1.0 } else { 0.0 });
                for &k in &metrics {
                    let e = point_error(k, p, &mr.metrics, &plant.run.metrics);
                    errors.get_mut(&(model.clone(), k)).expect("a pair")[panel][cell] = e;
                }
            }
        }
        Ok(Self {
            x,
            y,
            rows,
            columns,
            models,
            metrics,
            errors,
            valid,
            stuck,
            convergence,
        })
    }
}

/// The map's axes: x and y (with numeric values), rows and columns if the figure has them; every
/// other axis of the plan must have one value (a map has one point per cell).
fn map_axes(
    plan: &Plan,
    fig: &MapFigures,
) -> anyhow::Result<(MapAxis, MapAxis, Option<MapAxis>, Option<MapAxis>)> {
    let axis = |key: &String| -> anyhow::Result<MapAxis> {
        let a = plan
            .axes
            .iter()
            .find(|a| a.keys.contains(key))
            .ok_or_else(|| anyhow::anyhow!("figures: {key} is not an axis of the plan"))?;
        let i = a.keys.iter().position(|k| k == key).expect("found");
        Ok(MapAxis {
            key: key.clone(),
            values: a.values.iter().map(|row| row[i].clone()).collect(),
        })
    };
    let x = axis(&fig.x)?;
    let y = axis(&fig.y)?;
    for a in [&x, &y] {
        anyhow::ensure!(
            a.numbers().iter().all(Option::is_some),
            "figures: the values of {} must be numbers",
            a.key
        );
    }
    let rows = fig.rows.as_ref().map(axis).transpose()?;
    let columns = fig.columns.as_ref().map(axis).transpose()?;
    let used: Vec<&String> = [
        Some(&fig.x),
        Some(&fig.y),
        fig.rows.as_ref(),
        fig.columns.as_ref(),
    ]
    .into_iter()
    .flatten()
    .collect();
    for a in &plan.axes {
        if a.values.len() > 1 && !a.keys.iter().any(|k| used.contains(&k)) {
            anyhow::bail!(
                "figures: the axis {:?} has {} values but is not one of x, y, rows, columns: a map needs one point per cell",
                a.keys,
                a.values.len()
            );
        }
    }
    Ok((x, y, rows, columns))
}
