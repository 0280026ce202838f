//! Sweep plans (TOML): a base scenario, fixed settings, axes of values, what to evaluate at each
//! point and which metrics to keep.
//!
//! Every key that names a scenario field is a dotted path into the scenario's TOML table
//! (`friction.eps`, `actuation.alpha`, `numerics.cells`, ...), so any field the scenario format
//! has now or gains later can be swept; the values are checked by the scenario's own parser when
//! the points are resolved ([`crate::point`]). See `plans/validity.toml` for a complete plan.

use serde::{Deserialize, Serialize};
use std::path::Path;

use crawler_facts::Metric;
use crawler_policies::Params;

mod parse;

use parse::{axis, base_scenario, check_figures, chosen_metrics, evaluation, Bad};

/// Why a plan could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The file could not be read.
    #[error("cannot read plan {path}: {cause}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        cause: std::io::Error,
    },
    /// Not valid TOML, an unknown key or a wrong type (the message gives the line).
    #[error("plan {origin}: {message}")]
    Syntax {
        /// The file name.
        origin: String,
        /// The parser's message.
        message: String,
    },
    /// A value that is not allowed.
    #[error("plan {origin}: invalid {field} = {value}: allowed {allowed}")]
    Invalid {
        /// The file name.
        origin: String,
        /// The plan field at fault.
        field: String,
        /// The offending value.
        value: String,
        /// What is allowed.
        allowed: String,
    },
}

/// The models a plan may evaluate.
pub const MODELS: [&str; 2] = ["paper", "improved"];

/// Largest number of points in one plan (a guard against a typo making 10^9 points).
pub const MAX_POINTS: usize = 1_000_000;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlan {
    name: String,
    #[serde(default)]
    description: String,
    scenario: Option<String>,
    #[serde(default)]
    metrics: Option<Vec<String>>,
    #[serde(default)]
    set: toml::Table,
    #[serde(default)]
    axes: Vec<RawAxis>,
    evaluate: RawEvaluate,
    figures: Option<MapFigures>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAxis {
    key: Option<String>,
    keys: Option<Vec<String>>,
    values: Option<Vec<toml::Value>>,
    linspace: Option<Range>,
    logspace: Option<Range>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct Range {
    start: f64,
    stop: f64,
    num: i64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEvaluate {
    #[serde(default)]
    plant: bool,
    #[serde(default = "yes")]
    convergence: bool,
    #[serde(default)]
    models: Vec<String>,
    policy: Option<RawPolicy>,
}

fn yes() -> bool {
    true
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPolicy {
    name: String,
    #[serde(default)]
    params: toml::Table,
}

/// One axis: one or more scenario keys that change together, and their values.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Axis {
    /// Dotted scenario keys (one, or several zipped together).
    pub keys: Vec<String>,
    /// For each position on the axis, one value per key.
    pub values: Vec<Vec<toml::Value>>,
}

/// A co-simulated policy, evaluated in process (bit-identical to the co-simulation): a
/// registered policy and its parameters (`KEY=VALUE`, as `--param` takes them). The wave it
/// starts from is the point's (`actuation.*` keys).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolicySpec {
    /// Registered policy name (`crawler-controller policies`).
    pub name: String,
    /// Its parameters, `KEY=VALUE`.
    pub params: Vec<String>,
}

impl PolicySpec {
    /// The policy's parameters.
    pub fn params(&self) -> Params {
        Params::parse(&self.params).expect("validated when the plan was loaded")
    }
}

/// A plan's policy parameter as `--param` takes it: numbers in full precision, lists of
/// numbers separated by commas.
fn param_value(key: &str, v: &toml::Value) -> Result<String, String> {
    let number = |x: &toml::Value| match x {
        toml::Value::Integer(i) => Some(i.to_string()),
        toml::Value::Float(f) => Some(f.to_string()),
        _ => None,
    };
    match v {
        toml::Value::String(s) => Ok(s.clone()),
        toml::Value::Boolean(b) => Ok(b.to_string()),
        toml::Value::Array(xs) => xs
            .iter()
            .map(number)
            .collect::<Option<Vec<_>>>()
            .map(|xs| xs.join(","))
            .ok_or_else(|| format!("evaluate.policy.params.{key}: a list of numbers")),
        other => number(other).ok_or_else(|| format!("evaluate.policy.params.{key}")),
    }
}

/// What is evaluated at every point. It is part of each point's id.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Evaluate {
    /// Run the in-process plant under the scenario's wave.
    pub plant: bool,
    /// Also run the plant at twice the cells for a discretisation-error estimate (the reported
    /// plant values are those of the finer run).
    pub convergence: bool,
    /// Models (`paper`, `improved`), in a fixed order.
    pub models: Vec<String>,
    /// A policy run in closed loop with the plant.
    pub policy: Option<PolicySpec>,
}

/// The heat-map figures of a plan: a grid of panels, one heat map per panel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapFigures {
    /// Axis key on the horizontal axis of each panel.
    pub x: String,
    /// Axis key on the vertical axis of each panel.
    pub y: String,
    /// Axis key that changes from one row of panels to the next (optional).
    pub rows: Option<String>,
    /// Axis key that changes from one column of panels to the next (optional).
    pub columns: Option<String>,
}

/// A validated plan.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Short name: names the output files.
    pub name: String,
    /// One line of description.
    pub description: String,
    /// The plan file (for messages).
    pub origin: String,
    /// The base scenario's TOML text.
    pub base_toml: String,
    /// Where the base scenario came from (for messages).
    pub base_origin: String,
    /// Fixed settings applied to every point, dotted key -> value, in file order.
    pub set: Vec<(String, toml::Value)>,
    /// The axes, outermost first (the last axis changes fastest).
    pub axes: Vec<Axis>,
    /// What to evaluate.
    pub evaluate: Evaluate,
    /// The metrics kept in the results, in the metric table's order.
    pub metrics: Vec<Metric>,
    /// Figures to draw, if any.
    pub figures: Option<MapFigures>,
}

/// A plan or scenario file's text, read to at most
/// [`MAX_SCENARIO_BYTES`](crawler_physics::scenario::MAX_SCENARIO_BYTES) (a device or a file of
/// unbounded length is refused, not read to the end).
fn read_text(path: &Path) -> std::io::Result<String> {
    crawler_physics::framing::read_text_at_most(path, crawler_physics::scenario::MAX_SCENARIO_BYTES)
}

impl Plan {
    /// Loads a plan file; a relative `scenario` path is taken relative to the plan's folder.
    pub fn from_file(path: &Path) -> Result<Self, PlanError> {
        let text = read_text(path).map_err(|cause| PlanError::Io {
            path: path.display().to_string(),
            cause,
        })?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::from_toml(&text, &path.display().to_string(), &dir)
    }

    /// Parses a plan; `dir` resolves a relative `scenario` path. Without `scenario` the base is
    /// the paper's scenario.
    pub fn from_toml(text: &str, origin: &str, dir: &Path) -> Result<Self, PlanError> {
        let raw: RawPlan = toml::from_str(text).map_err(|e| PlanError::Syntax {
            origin: origin.to_string(),
            message: e.to_string(),
        })?;
        let bad = Bad { origin };
        if raw.name.is_empty()
            || !raw
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(bad.field(
                "name",
                &format!("{:?}", raw.name),
                "a non-empty name of ASCII letters, digits, '-' and '_' (it names the output files)",
            ));
        }
        let (base_toml, base_origin) = base_scenario(raw.scenario.as_deref(), dir, &bad)?;
        let mut set = Vec::new();
        flatten("", &raw.set, &mut set);
        for (k, _) in &set {
            check_key(k).map_err(|why| bad.field(&format!("set.{k:?}"), k, &why))?;
        }

        let mut axes = Vec::new();
        let mut seen: Vec<String> = set.iter().map(|(k, _)| k.clone()).collect();
        for (i, a) in raw.axes.iter().enumerate() {
            axes.push(axis(&format!("axes[{i}]"), a, &mut seen, &bad)?);
        }
        let count = axes
            .iter()
            .try_fold(1usize, |n, a| n.checked_mul(a.values.len()));
        match count {
            Some(n) if n <= MAX_POINTS => {}
            _ => {
                return Err(bad.field(
                    "axes",
                    &"the product of the axes' lengths",
                    &format!("at most {MAX_POINTS} points"),
                ))
            }
        }
        let evaluate = evaluation(&raw.evaluate, &bad)?;
        let metrics = chosen_metrics(raw.metrics.as_deref(), &bad)?;
        if let Some(f) = &raw.figures {
            check_figures(f, &axes, &evaluate, &bad)?;
        }
        Ok(Plan {
            name: raw.name,
            description: raw.description,
            origin: origin.to_string(),
            base_toml,
            base_origin,
            set,
            axes,
            evaluate,
            metrics,
            figures: raw.figures,
        })
    }

    /// True when the plan states a task: its base scenario has a `[task]` table, or a setting or
    /// an axis gives a `task.` key. Its results then carry each run's outcome against the task.
    pub fn states_task(&self) -> bool {
        let is_task = |k: &str| k == "task" || k.starts_with("task.");
        self.set.iter().any(|(k, _)| is_task(k))
            || self.axes.iter().any(|a| a.keys.iter().any(|k| is_task(k)))
            || toml::from_str::<toml::Table>(&self.base_toml).is_ok_and(|t| t.contains_key("task"))
    }

    /// Number of points (the product of the axes' lengths; 1 without axes).
    pub fn len(&self) -> usize {
        self.axes.iter().map(|a| a.values.len()).product()
    }

    /// True if the plan has no point (never: a plan without axes has one).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Flattens nested TOML tables into dotted keys (`{friction = {eps = 1}}` and
/// `"friction.eps" = 1` both give `friction.eps`).
fn flatten(prefix: &str, t: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (k, v) in t {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match v {
            toml::Value::Table(inner) => flatten(&key, inner, out),
            _ => out.push((key, v.clone())),
        }
    }
}

/// A dotted scenario key: `section.field` (or deeper), each part a TOML bare key.
fn check_key(k: &str) -> Result<(), String> {
    let parts: Vec<&str> = k.split('.').collect();
    let bare = |p: &str| {
        !p.is_empty()
            && p.chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    };
    if parts.len() >= 2 && parts.iter().all(|p| bare(p)) {
        Ok(())
    } else {
        Err("a dotted scenario key such as friction.eps or actuation.alpha (section.field)".into())
    }
}

/// `num` values from `start` to `stop` inclusive, evenly (or geometrically) spaced; the ends
/// are exact.
fn spaced(r: Range, log: bool) -> Result<Vec<f64>, (&'static str, String, String)> {
    if !r.start.is_finite() {
        return Err(("start", r.start.to_string(), "a finite number".into()));
    }
    if !r.stop.is_finite() {
        return Err(("stop", r.stop.to_string(), "a finite number".into()));
    }
    if !(1..=100_000).contains(&r.num) {
        return Err(("num", r.num.to_string(), "1 <= num <= 100000".into()));
    }
    if log && (r.start <= 0.0 || r.stop <= 0.0) {
        let v = if r.start <= 0.0 { r.start } else { r.stop };
        return Err((
            if r.start <= 0.0 { "start" } else { "stop" },
            v.to_string(),
            "a number > 0 (logspace spaces the values geometrically between start and stop)".into(),
        ));
    }
    let n = r.num as usize;
    if n == 1 {
        return Ok(vec![r.start]);
    }
    let last = (n - 1) as f64;
    Ok((0..n)
        .map(|i| {
            if i == n - 1 {
                r.stop
            } else if log {
                (r.start.ln() + (r.stop.ln() - r.start.ln()) * i as f64 / last).exp()
            } else {
                r.start + (r.stop - r.start) * i as f64 / last
            }
        })
        .collect())
}

/// The Parquet type of an axis column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColumnType {
    /// 64-bit float (any number; integers and floats mixed).
    Float,
    /// 64-bit integer (all values integers).
    Int,
    /// UTF-8 text.
    Text,
    /// Boolean.
    Bool,
}

/// The column type of each key of an axis, or the key whose values mix kinds.
pub fn column_type(
    keys: &[String],
    values: &[Vec<toml::Value>],
) -> Result<Vec<ColumnType>, (String, String)> {
    let mut out = Vec::new();
    for (i, k) in keys.iter().enumerate() {
        let kinds: Vec<ColumnType> = values
            .iter()
            .map(|row| match &row[i] {
                toml::Value::Integer(_) => ColumnType::Int,
                toml::Value::Float(_) => ColumnType::Float,
                toml::Value::String(_) => ColumnType::Text,
                _ => ColumnType::Bool,
            })
            .collect();
        let t = if kinds.iter().all(|t| *t == ColumnType::Int) {
            ColumnType::Int
        } else if kinds
            .iter()
            .all(|t| matches!(t, ColumnType::Int | ColumnType::Float))
        {
            ColumnType::Float
        } else if kinds.iter().all(|t| *t == kinds[0]) {
            kinds[0]
        } else {
            return Err((
                k.clone(),
                "values of one kind (numbers, strings or booleans)".into(),
            ));
        };
        out.push(t);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(text: &str) -> Result<Plan, PlanError> {
        Plan::from_toml(text, "test.toml", Path::new("."))
    }

    const EVAL: &str = "[evaluate]\nmodels = [\"paper\"]\n";

    #[test]
    fn plan_and_scenario_files_of_unbounded_length_are_refused_not_read_to_the_end() {
        let e = Plan::from_file(Path::new("/dev/zero"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("larger than"), "{e}");
        let e = Plan::from_toml(
            &format!("name = \"t\"\nscenario = \"zero\"\n{EVAL}"),
            "test.toml",
            Path::new("/dev"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("larger than"), "{e}");
    }

    #[test]
    fn linspace_and_logspace_hit_their_ends_exactly() {
        let p = plan(&format!(
            "name = \"t\"\n[[axes]]\nkey = \"friction.eps\"\nlinspace = {{ start = 0.0, stop = 1.5, num = 31 }}\n\
             [[axes]]\nkey = \"actuation.alpha\"\nlogspace = {{ start = 0.2, stop = 2.0, num = 3 }}\n{EVAL}"
        ))
        .unwrap();
        assert_eq!(p.len(), 93);
        let eps: Vec<f64> = p.axes[0]
            .values
            .iter()
            .map(|v| v[0].as_float().unwrap())
            .collect();
        assert_eq!(eps[0], 0.0);
        assert_eq!(eps[30], 1.5);
        assert!((eps[10] - 0.5).abs() < 1e-15);
        let a: Vec<f64> = p.axes[1]
            .values
            .iter()
            .map(|v| v[0].as_float().unwrap())
            .collect();
        assert_eq!(a[0], 0.2);
        assert_eq!(a[2], 2.0);
        // geometric: the middle value is the geometric mean of the ends
        assert!((a[1] - (0.4f64).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn errors_name_the_field_the_value_and_what_is_allowed() {
        let cases = [
            ("name = \"a b\"\n[evaluate]\nplant = true\n", "name"),
            (
                "name = \"t\"\n[[axes]]\nkey = \"eps\"\nvalues = [1.0]\n[evaluate]\nplant = true\n",
                "dotted scenario key",
            ),
            (
                "name = \"t\"\n[[axes]]\nkey = \"friction.eps\"\nlinspace = { start = 0.0, stop = 1.0, num = 0 }\n[evaluate]\nplant = true\n",
                "axes[0].linspace.num = 0",
            ),
            (
                "name = \"t\"\n[[axes]]\nkey = \"actuation.alpha\"\nlogspace = { start = 0.0, stop = 1.0, num = 3 }\n[evaluate]\nplant = true\n",
                "axes[0].logspace.start = 0",
            ),
            (
                "name = \"t\"\n[[axes]]\nkey = \"friction.eps\"\nvalues = [1.0, \"x\"]\n[evaluate]\nplant = true\n",
                "values of one kind",
            ),
            ("name = \"t\"\n[evaluate]\nmodels = [\"exact\"]\n", "evaluate.models = exact"),
            ("name = \"t\"\n[evaluate]\n", "evaluate = nothing"),
            (
                "name = \"t\"\n[evaluate]\npolicy = { name = \"nope\" }\n",
                "evaluate.policy.name = nope",
            ),
            (
                "name = \"t\"\nmetrics = [\"speed\"]\n[evaluate]\nplant = true\n",
                "metrics = speed",
            ),
            (
                "name = \"t\"\n[[axes]]\nkey = \"friction.eps\"\nvalues = [1.0]\n[[axes]]\nkey = \"friction.eps\"\nvalues = [2.0]\n[evaluate]\nplant = true\n",
                "no other axis",
            ),
            ("name = \"t\"\nbogus = 1\n[evaluate]\nplant = true\n", "unknown field"),
        ];
        for (text, needle) in cases {
            let e = plan(text).expect_err(text).to_string();
            assert!(e.contains(needle), "{e:?} should contain {needle:?}");
            assert!(e.starts_with("plan test.toml"), "{e}");
        }
    }

    #[test]
    fn zipped_axes_take_one_value_per_key() {
        let p = plan(&format!(
            "name = \"t\"\n[[axes]]\nkeys = [\"actuation.k\", \"numerics.cells\"]\nvalues = [[6.283185307179586, 64], [12.566370614359172, 128]]\n{EVAL}"
        ))
        .unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(
            column_type(&p.axes[0].keys, &p.axes[0].values).unwrap(),
            vec![ColumnType::Float, ColumnType::Int]
        );
        let e = plan(&format!(
            "name = \"t\"\n[[axes]]\nkeys = [\"actuation.k\", \"numerics.cells\"]\nvalues = [[6.28]]\n{EVAL}"
        ))
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("axes[0].values[0]") && e.contains("an array of 2 values"),
            "{e}"
        );
    }
}
