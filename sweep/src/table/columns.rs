//! The table's columns, section by section: the point (index, id, axes, resolved inputs), the
//! plant, each model, the policy, and the evaluation's error and wall time. A section's columns
//! are present when the plan evaluates it; the task's columns when the plan states a task.

use std::collections::HashMap;
use std::sync::Arc;

use arrow_array::{
    ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray, UInt64Array,
};
use arrow_schema::{DataType, Field, Schema};
use crawler_physics::task::TaskReport;

use crate::plan::{column_type, Axis, ColumnType, Plan};
use crate::point::Point;
use crate::record::{ModelResult, PlantRun, Record};

use super::{conv_error, point_error, FLOOR_SHARE, QUANTISED_AGREEMENT};

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

/// The columns so far, over the points and their records (same order).
struct Columns<'a> {
    points: &'a [Point],
    records: &'a [Record],
    cols: Vec<Column>,
}

/// What a column reads of one row.
type Cell<'f, T> = &'f dyn Fn(&Point, &Record) -> Option<T>;

impl Columns<'_> {
    fn cells<T>(&self, f: Cell<'_, T>) -> Vec<Option<T>> {
        self.points
            .iter()
            .zip(self.records)
            .map(|(p, r)| f(p, r))
            .collect()
    }

    fn push(
        &mut self,
        name: impl Into<String>,
        unit: &'static str,
        doc: impl Into<String>,
        data: Data,
    ) {
        self.cols.push(Column {
            name: name.into(),
            unit,
            doc: doc.into(),
            data,
        });
    }

    fn f64(
        &mut self,
        name: impl Into<String>,
        unit: &'static str,
        doc: impl Into<String>,
        f: Cell<'_, f64>,
    ) {
        let data = Data::F64(self.cells(f));
        self.push(name, unit, doc, data);
    }

    fn u64(
        &mut self,
        name: impl Into<String>,
        unit: &'static str,
        doc: impl Into<String>,
        f: Cell<'_, u64>,
    ) {
        let data = Data::U64(self.cells(f));
        self.push(name, unit, doc, data);
    }

    fn text(&mut self, name: impl Into<String>, doc: impl Into<String>, f: Cell<'_, String>) {
        let data = Data::Text(self.cells(f));
        self.push(name, "", doc, data);
    }

    fn boolean(&mut self, name: impl Into<String>, doc: impl Into<String>, f: Cell<'_, bool>) {
        let data = Data::Bool(self.cells(f));
        self.push(name, "", doc, data);
    }

    /// The point's index and id.
    fn identity(&mut self) {
        self.u64(
            "index",
            "1",
            "position of the point in the plan (row-major over the axes, the last fastest)",
            &|p, _| Some(p.index as u64),
        );
        self.text(
            "point_id",
            "SHA-256 of the resolved scenario, what is evaluated, the result format and the code fingerprint",
            &|p, _| Some(p.id.clone()),
        );
    }

    /// One column per axis key, typed as the plan gives its values.
    fn axes(&mut self, axes: &[Axis]) -> anyhow::Result<()> {
        for a in axes {
            let types = column_type(&a.keys, &a.values)
                .map_err(|(k, why)| anyhow::anyhow!("{k}: {why}"))?;
            for (key, t) in a.keys.iter().zip(types) {
                let value = |p: &Point| -> toml::Value {
                    p.assignments
                        .iter()
                        .find(|(k, _)| k == key)
                        .map(|(_, v)| v.clone())
                        .expect("every point has every axis")
                };
                let data = match t {
                    ColumnType::Float => Data::F64(self.cells(&|p, _| {
                        let v = value(p);
                        v.as_float().or(v.as_integer().map(|i| i as f64))
                    })),
                    ColumnType::Int => Data::I64(self.cells(&|p, _| value(p).as_integer())),
                    ColumnType::Text => {
                        Data::Text(self.cells(&|p, _| value(p).as_str().map(str::to_string)))
                    }
                    ColumnType::Bool => Data::Bool(self.cells(&|p, _| value(p).as_bool())),
                };
                self.push(
                    key.clone(),
                    "",
                    format!("axis value of scenario key {key}, as given in the plan"),
                    data,
                );
            }
        }
        Ok(())
    }

    /// The point's resolved inputs, its cells and its scenario file.
    fn inputs(&mut self) {
        for (name, unit, doc, f) in INPUTS {
            self.f64(name, unit, doc, &|p, _| {
                let x = f(p);
                x.is_finite().then_some(x)
            });
        }
        let data = Data::I64(self.cells(&|p, _| Some(p.scenario.plant.numerics.cells as i64)));
        self.push(
            "cells",
            "1",
            "the point's number of cells N (numerics.cells)",
            data,
        );
        self.text(
            "scenario",
            "the point's resolved scenario file (TOML): every input",
            &|p, _| Some(p.toml.clone()),
        );
    }

    /// The reported plant run: its resolution, digest, metrics (with their discretisation-error
    /// estimates under a convergence check) and task.
    fn plant(&mut self, plan: &Plan) {
        fn run(r: &Record) -> Option<&PlantRun> {
            r.plant.as_ref().map(|p| &p.run)
        }
        self.u64(
            "plant.cells",
            "1",
            "cells of the reported plant run (2N with the convergence check)",
            &|_, r| run(r).map(|r| r.cells),
        );
        self.f64(
            "plant.dt",
            "s",
            "internal step of the reported run",
            &|_, r| run(r).map(|r| r.dt),
        );
        self.u64(
            "plant.steps",
            "1",
            "internal steps of the reported run",
            &|_, r| run(r).map(|r| r.steps),
        );
        self.f64(
            "plant.window_periods",
            "1",
            "forcing periods in the averaging window",
            &|_, r| run(r).map(|r| r.window_periods),
        );
        self.f64(
            "plant.momentum_residual",
            "1",
            "relative residual of the discrete momentum balance",
            &|_, r| run(r).and_then(|r| r.momentum_residual),
        );
        self.text(
            "plant.state_digest",
            "CRC-32 of the final state of the reported run",
            &|_, r| run(r).map(|r| r.state_digest.clone()),
        );
        for &m in &plan.metrics {
            self.f64(
                format!("plant.{m}"),
                m.unit(),
                format!("plant's {}, {}", m.info().label, m.info().doc),
                &|_, r| run(r).and_then(|r| r.metrics.get(m)),
            );
            if plan.evaluate.convergence {
                let how = if m.info().share {
                    "; null where numerics.courant is known to bias the stick statistics (the two runs share the bias)".to_string()
                } else {
                    format!(" / max(|value(2N)|, {FLOOR_SHARE:e} of the point's scale); null where the two agree to {QUANTISED_AGREEMENT:e} (where the wave moves one cell per step the speed is quantised, so N and 2N can agree exactly while both are off)")
                };
                self.f64(
                    format!("plant.{m}.conv_error"),
                    "1",
                    format!(
                        "estimated discretisation error of plant.{m}: |value(2N) - value(N)|{how}"
                    ),
                    &|p, r| r.plant.as_ref().and_then(|pr| conv_error(pr, m, p)),
                );
            }
        }
        if plan.states_task() {
            self.task("plant", &run);
        }
    }

    /// The `mi`-th model of the plan: validity, metrics and, with the plant, their errors.
    fn model(&mut self, plan: &Plan, mi: usize, model: &str) {
        fn model_of(r: &Record, mi: usize) -> Option<&ModelResult> {
            r.models.get(mi)
        }
        self.boolean(
            format!("{model}.valid"),
            format!("whether the {model} model's formulas apply"),
            &|_, r| model_of(r, mi).map(|x| x.valid),
        );
        self.text(
            format!("{model}.reason"),
            format!("why the {model} model does not apply"),
            &|_, r| model_of(r, mi).and_then(|x| x.reason.clone()),
        );
        for &m in &plan.metrics {
            self.f64(
                format!("{model}.{m}"),
                m.unit(),
                format!("{model} model's {m}"),
                &|_, r| model_of(r, mi).and_then(|x| x.metrics.get(m)),
            );
            if plan.evaluate.plant {
                let doc = if m.info().share {
                    format!("{model}.{m} - plant.{m}")
                } else {
                    format!(
                        "{model}.{m} / plant.{m} - 1 (the denominator at least {FLOOR_SHARE:e} of the point's scale; null where undefined)"
                    )
                };
                self.f64(format!("{model}.{m}.error"), "1", doc, &|p, r| {
                    let plant = r.plant.as_ref()?;
                    point_error(m, p, &model_of(r, mi)?.metrics, &plant.run.metrics)
                });
            }
        }
    }

    /// The policy's run: its name, whether its window was steady, its last wave, its metrics and
    /// its task.
    fn policy(&mut self, plan: &Plan) {
        self.text("policy.name", "the policy", &|_, r| {
            r.policy.as_ref().map(|p| p.policy.clone())
        });
        self.boolean(
            "policy.steady",
            "true: steady window; false: run averages of a time-varying policy",
            &|_, r| r.policy.as_ref().map(|p| p.steady),
        );
        for (i, (n, u)) in [("f0", "N"), ("k", "rad/m"), ("omega", "rad/s")]
            .into_iter()
            .enumerate()
        {
            self.f64(
                format!("policy.{n}"),
                u,
                format!("{n} of the last wave the policy commanded"),
                &|_, r| r.policy.as_ref().and_then(|p| p.wave).map(|w| w[i]),
            );
        }
        for &m in &plan.metrics {
            self.f64(
                format!("policy.{m}"),
                m.unit(),
                format!("plant's {m} under the policy"),
                &|_, r| r.policy.as_ref().and_then(|p| p.run.metrics.get(m)),
            );
        }
        if plan.states_task() {
            fn run(r: &Record) -> Option<&PlantRun> {
                r.policy.as_ref().map(|p| &p.run)
            }
            self.task("policy", &run);
        }
    }

    /// How the run picked by `run` did against the scenario's task (the plant's report).
    fn task(&mut self, prefix: &str, run: &dyn Fn(&Record) -> Option<&PlantRun>) {
        fn task_of<'r>(
            r: &'r Record,
            run: &dyn Fn(&Record) -> Option<&PlantRun>,
        ) -> Option<&'r TaskReport> {
            run(r)?.task.as_ref()
        }
        self.text(
            format!("{prefix}.task.outcome"),
            format!(
                "how the run did against the task: {}",
                crawler_facts::Outcome::ALLOWED
            ),
            &|_, r| task_of(r, run).map(|t| t.outcome.as_str().to_string()),
        );
        type TaskField = (
            &'static str,
            &'static str,
            &'static str,
            fn(&TaskReport) -> Option<f64>,
        );
        let fields: [TaskField; 6] = [
            (
                "distance",
                "m",
                "distance the centre of mass travelled",
                |t| Some(t.distance),
            ),
            (
                "time_to_distance",
                "s",
                "time until the task's distance was reached",
                |t| t.time_to_distance,
            ),
            ("energy_used", "J", "net actuator work over the run", |t| {
                Some(t.energy_used)
            }),
            ("max_stress", "Pa", "largest stress over the run", |t| {
                Some(t.max_stress)
            }),
            (
                "time_over_sigma_max",
                "s",
                "time the stress spent above sigma_max",
                |t| Some(t.time_over_sigma_max),
            ),
            (
                "stress_exceeded_at",
                "s",
                "time when the stress had been above sigma_max for longer than the tolerance",
                |t| t.stress_exceeded_at,
            ),
        ];
        for (name, unit, doc, f) in fields {
            self.f64(format!("{prefix}.task.{name}"), unit, doc, &|_, r| {
                task_of(r, run).and_then(f)
            });
        }
    }

    /// Why a point failed, and its wall time.
    fn evaluation(&mut self) {
        self.text(
            "error",
            "why the point's evaluation failed (null: it did not)",
            &|_, r| r.error.clone(),
        );
        self.f64(
            "wall_time",
            "s",
            "wall time of the point's evaluation (the only column that differs between runs)",
            &|_, r| Some(r.wall_time),
        );
    }
}

/// A resolved input column: name, unit, doc, and how it is read off the point.
type Input = (&'static str, &'static str, &'static str, fn(&Point) -> f64);

/// The resolved inputs, in column order.
const INPUTS: [Input; 18] = [
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

/// The results of `points` (plan order) with their `records` (same order) as one batch.
pub fn batch(plan: &Plan, points: &[Point], records: &[Record]) -> anyhow::Result<RecordBatch> {
    assert_eq!(points.len(), records.len());
    let mut c = Columns {
        points,
        records,
        cols: Vec::new(),
    };
    c.identity();
    c.axes(&plan.axes)?;
    c.inputs();
    if plan.evaluate.plant {
        c.plant(plan);
    }
    for (mi, model) in plan.evaluate.models.iter().enumerate() {
        c.model(plan, mi, model);
    }
    if plan.evaluate.policy.is_some() {
        c.policy(plan);
    }
    c.evaluation();
    let (fields, arrays): (Vec<Field>, Vec<ArrayRef>) =
        c.cols.into_iter().map(Column::array).unzip();
    Ok(RecordBatch::try_new(Arc::new(Schema::new(fields)), arrays)?)
}
