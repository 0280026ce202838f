//! The points of a plan: the base scenario with the plan's settings and one value of every axis
//! substituted into its TOML table, resolved and validated by the scenario's own parser, and
//! identified by a hash of what determines their results.

use serde::Serialize;
use sha2::{Digest, Sha256};

use crawler_physics::scenario::{Overrides, Scenario};

use crate::plan::{Evaluate, Plan};

/// Version of the result format; part of every id, so changing what a record holds never mixes
/// old and new records.
pub const FORMAT: u32 = 2;

/// Fingerprint of the code that computes results (plant, models, policies, evaluation), made at
/// build time from their sources; part of every id.
pub const CODE: &str = env!("CRAWLER_SWEEP_CODE");

/// One point of a plan.
#[derive(Debug, Clone)]
pub struct Point {
    /// Position in the plan (row-major over the axes, the last axis fastest).
    pub index: usize,
    /// The axis values of this point, key by key.
    pub assignments: Vec<(String, toml::Value)>,
    /// The resolved scenario's TOML (the base with the settings and axis values substituted).
    pub toml: String,
    /// The validated scenario.
    pub scenario: Scenario,
    /// Hex SHA-256 of the point's canonical description (see [`point_id`]).
    pub id: String,
}

/// Why a point could not be resolved.
#[derive(Debug, thiserror::Error)]
pub enum PointError {
    /// The base scenario is not TOML.
    #[error("scenario {origin}: {message}")]
    Base {
        /// Where the base came from.
        origin: String,
        /// The parser's message.
        message: String,
    },
    /// A key runs through a value that is not a table.
    #[error(
        "plan {plan}, point {index} ({at}): cannot set {key}: {part} is a value, not a section"
    )]
    NotATable {
        /// The plan file.
        plan: String,
        /// The point's index.
        index: usize,
        /// The point's axis values.
        at: String,
        /// The key.
        key: String,
        /// The part of the key that is not a table.
        part: String,
    },
    /// The scenario refused the point's values.
    #[error("plan {plan}, point {index} ({at}): {cause}")]
    Scenario {
        /// The plan file.
        plan: String,
        /// The point's index.
        index: usize,
        /// The point's axis values.
        at: String,
        /// The scenario's own message (names the field, the value and what is allowed).
        cause: Box<crawler_physics::scenario::ScenarioError>,
    },
}

/// Sets `key` (dotted) in `table`, creating sections as needed. `actuation.alpha` and
/// `actuation.omega` exclude each other (as the command-line flags do): setting one removes the
/// other.
fn assign(table: &mut toml::Table, key: &str, value: &toml::Value) -> Result<(), String> {
    let parts: Vec<&str> = key.split('.').collect();
    let (last, sections) = parts.split_last().expect("a checked dotted key");
    let mut t = table;
    for (i, part) in sections.iter().enumerate() {
        let entry = t
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        t = match entry {
            toml::Value::Table(inner) => inner,
            _ => return Err(parts[..=i].join(".")),
        };
    }
    if sections == ["actuation"] {
        match *last {
            "alpha" => {
                t.remove("omega");
            }
            "omega" => {
                t.remove("alpha");
            }
            _ => {}
        }
    }
    t.insert(last.to_string(), value.clone());
    Ok(())
}

/// "key = value, key = value" for messages.
pub fn describe(assignments: &[(String, toml::Value)]) -> String {
    if assignments.is_empty() {
        return "the base scenario".into();
    }
    assignments
        .iter()
        .map(|(k, v)| format!("{k} = {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The canonical description a point's id hashes: result format, code fingerprint, the resolved
/// scenario (its name and description left out: labels do not change results) and what is
/// evaluated. Equal descriptions mean equal results, so plans that share points share them.
#[derive(Serialize)]
struct Canonical<'a> {
    format: u32,
    code: &'a str,
    scenario: &'a Scenario,
    evaluate: &'a Evaluate,
}

/// The id of `scenario` evaluated as `evaluate`: hex SHA-256 of [`Canonical`] as JSON (struct
/// fields in declaration order, floats in shortest round-trip form).
pub fn point_id(scenario: &Scenario, evaluate: &Evaluate) -> String {
    let mut s = scenario.clone();
    s.name.clear();
    s.description.clear();
    let c = Canonical {
        format: FORMAT,
        code: CODE,
        scenario: &s,
        evaluate,
    };
    let json = serde_json::to_vec(&c).expect("a scenario serialises");
    let digest = Sha256::digest(&json);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// Resolves the point with the given axis values.
pub fn resolve_one(
    plan: &Plan,
    base: &toml::Table,
    index: usize,
    assignments: Vec<(String, toml::Value)>,
) -> Result<Point, PointError> {
    let at = describe(&assignments);
    let mut table = base.clone();
    for (k, v) in plan.set.iter().chain(assignments.iter()) {
        assign(&mut table, k, v).map_err(|part| PointError::NotATable {
            plan: plan.origin.clone(),
            index,
            at: at.clone(),
            key: k.clone(),
            part,
        })?;
    }
    let text = toml::to_string(&table).expect("a TOML table serialises");
    let scenario =
        Scenario::from_toml(&text, &plan.base_origin, &Overrides::default()).map_err(|cause| {
            PointError::Scenario {
                plan: plan.origin.clone(),
                index,
                at: at.clone(),
                cause: Box::new(cause),
            }
        })?;
    let id = point_id(&scenario, &plan.evaluate);
    Ok(Point {
        index,
        assignments,
        toml: text,
        scenario,
        id,
    })
}

/// Every point of the plan, in plan order; the first point the scenario refuses stops it with
/// the scenario's message.
pub fn resolve(plan: &Plan) -> Result<Vec<Point>, PointError> {
    let base: toml::Table = toml::from_str(&plan.base_toml).map_err(|e| PointError::Base {
        origin: plan.base_origin.clone(),
        message: e.to_string(),
    })?;
    let n = plan.len();
    let mut points = Vec::with_capacity(n);
    for index in 0..n {
        // row-major: the last axis changes fastest
        let mut rest = index;
        let mut pos = vec![0usize; plan.axes.len()];
        for (i, a) in plan.axes.iter().enumerate().rev() {
            pos[i] = rest % a.values.len();
            rest /= a.values.len();
        }
        let assignments: Vec<(String, toml::Value)> = plan
            .axes
            .iter()
            .zip(&pos)
            .flat_map(|(a, &j)| a.keys.iter().cloned().zip(a.values[j].iter().cloned()))
            .collect();
        points.push(resolve_one(plan, &base, index, assignments)?);
    }
    Ok(points)
}

/// The distinct caveats of the points' scenarios ([`Scenario::caveats`]: settings known to bias
/// the results), each with the number of points it applies to, in order of first appearance.
pub fn caveats(points: &[Point]) -> Vec<(String, usize)> {
    let mut out: Vec<(String, usize)> = Vec::new();
    for p in points {
        for c in p.scenario.caveats() {
            let text = c.to_string();
            match out.iter_mut().find(|(t, _)| *t == text) {
                Some((_, n)) => *n += 1,
                None => out.push((text, 1)),
            }
        }
    }
    out
}

/// Rough cost of a plant run of `s`, in cell updates (cells x internal steps), for scheduling
/// the longest points first and for the progress bar.
pub fn plant_cost(s: &Scenario) -> f64 {
    let n = s.plant.numerics.cells as f64;
    match s.plant.discretisation() {
        Ok(d) => n * (s.t_end / d.dt),
        Err(_) => n * n,
    }
}

/// Rough cost of evaluating `point` as `evaluate` (plant cell updates; models count as one
/// thousandth of a plant run).
pub fn cost(point: &Point, evaluate: &Evaluate) -> f64 {
    let c = plant_cost(&point.scenario);
    let mut total = 1.0;
    if evaluate.plant {
        // a second run at twice the cells costs about 4x (twice the steps of twice the cells)
        total += c * if evaluate.convergence { 5.0 } else { 1.0 };
    }
    if evaluate.policy.is_some() {
        total += c;
    }
    total + 1e-3 * c * evaluate.models.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn plan(text: &str) -> Plan {
        Plan::from_toml(text, "test.toml", Path::new(".")).unwrap()
    }

    #[test]
    fn axis_values_reach_the_scenario_and_ids_follow_the_physics() {
        let p = plan(
            "name = \"t\"\n[set]\nnumerics.t_end = 7.0\n[[axes]]\nkey = \"friction.eps\"\nvalues = [0.5, 1.0]\n\
             [[axes]]\nkey = \"actuation.alpha\"\nvalues = [0.5, 1.5]\n[evaluate]\nmodels = [\"paper\"]\n",
        );
        let pts = resolve(&p).unwrap();
        assert_eq!(pts.len(), 4);
        // row-major, last axis fastest
        assert_eq!(pts[1].scenario.plant.friction.eps, 0.5);
        assert!((pts[1].scenario.alpha() - 1.5).abs() < 1e-12);
        assert_eq!(pts[2].scenario.plant.friction.eps, 1.0);
        assert_eq!(pts[3].scenario.t_end, 7.0);
        // every point differs, so every id does
        let mut ids: Vec<&str> = pts.iter().map(|p| p.id.as_str()).collect();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), 4);
        // the same physics reached another way (omega instead of alpha, another name) shares the id
        let omega = pts[3].scenario.wave.omega;
        let q =
            plan("name = \"other\"\n[set]\nname = { x = 1 }\n[evaluate]\nmodels = [\"paper\"]\n");
        assert!(resolve(&q).is_err(), "a key through a value is refused");
        let q = plan(&format!(
            "name = \"other\"\n[set]\nnumerics.t_end = 7.0\nfriction.eps = 1.0\nactuation.omega = {omega:?}\n[evaluate]\nmodels = [\"paper\"]\n"
        ));
        let same = resolve(&q).unwrap();
        assert_eq!(same[0].id, pts[3].id);
        // evaluating something else is another point
        let r = plan(
            "name = \"t\"\n[set]\nnumerics.t_end = 7.0\nfriction.eps = 1.0\nactuation.alpha = 1.5\n[evaluate]\nmodels = [\"paper\", \"improved\"]\n",
        );
        assert_ne!(resolve(&r).unwrap()[0].id, pts[3].id);
    }

    #[test]
    fn the_scenario_refuses_bad_values_with_its_own_message() {
        let p = plan(
            "name = \"t\"\n[[axes]]\nkey = \"friction.n_f\"\nvalues = [0.5, 1.5]\n[evaluate]\nplant = true\n",
        );
        let e = resolve(&p).unwrap_err().to_string();
        assert!(e.contains("point 1 (friction.n_f = 1.5)"), "{e}");
        assert!(
            e.contains("friction.n_f = 1.5: allowed 0 <= friction.n_f <= 1"),
            "{e}"
        );
        let p = plan(
            "name = \"t\"\n[[axes]]\nkey = \"friction.unknown_field\"\nvalues = [1.0]\n[evaluate]\nplant = true\n",
        );
        let e = resolve(&p).unwrap_err().to_string();
        assert!(
            e.contains("unknown field") && e.contains("unknown_field"),
            "{e}"
        );
    }
}
