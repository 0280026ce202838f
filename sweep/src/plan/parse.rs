//! Reading a plan's parts: the base scenario, each axis, what is evaluated, the metrics kept and
//! the figures, each checked with an error naming the field, its value and what is allowed.

use std::path::{Path, PathBuf};

use crawler_facts::Metric;

use super::*;

/// Makes the plan's errors: the plan file, the field at fault, its value and what is allowed.
pub(super) struct Bad<'a> {
    pub(super) origin: &'a str,
}

impl Bad<'_> {
    pub(super) fn field(
        &self,
        field: &str,
        value: &dyn std::fmt::Display,
        allowed: &str,
    ) -> PlanError {
        PlanError::Invalid {
            origin: self.origin.to_string(),
            field: field.to_string(),
            value: value.to_string(),
            allowed: allowed.to_string(),
        }
    }
}

/// The base scenario's text and where it came from: the file `scenario` (relative to `dir`) or,
/// without one, the paper's scenario.
pub(super) fn base_scenario(
    scenario: Option<&str>,
    dir: &Path,
    bad: &Bad,
) -> Result<(String, String), PlanError> {
    let Some(p) = scenario else {
        return Ok((
            crawler_physics::scenario::PAPER_TOML.to_string(),
            "<embedded paper.toml>".to_string(),
        ));
    };
    let path: PathBuf = dir.join(p);
    let text = read_text(&path).map_err(|cause| {
        bad.field(
            "scenario",
            &format!("{p:?}"),
            &format!(
                "a readable scenario file (relative to the plan's folder); reading {} failed: {cause}",
                path.display()
            ),
        )
    })?;
    Ok((text, path.display().to_string()))
}

/// The axis `a` (named `field` in messages); its keys must not be in `seen` (other axes and the
/// settings), and are added to it.
pub(super) fn axis(
    field: &str,
    a: &RawAxis,
    seen: &mut Vec<String>,
    bad: &Bad,
) -> Result<Axis, PlanError> {
    let keys = match (&a.key, &a.keys) {
        (Some(k), None) => vec![k.clone()],
        (None, Some(ks)) if !ks.is_empty() => ks.clone(),
        _ => {
            return Err(bad.field(
                field,
                &"key/keys",
                "exactly one of key = \"section.field\" or keys = [\"...\", ...] (non-empty)",
            ))
        }
    };
    for k in &keys {
        check_key(k).map_err(|why| bad.field(&format!("{field}.key"), k, &why))?;
        if seen.contains(k) {
            return Err(bad.field(
                &format!("{field}.key"),
                k,
                "a key that no other axis and no [set] entry gives",
            ));
        }
        seen.push(k.clone());
    }
    let given = [
        a.values.is_some(),
        a.linspace.is_some(),
        a.logspace.is_some(),
    ];
    if given.iter().filter(|g| **g).count() != 1 {
        return Err(bad.field(
            field,
            &"values/linspace/logspace",
            "exactly one of values = [...], linspace = { start, stop, num }, logspace = { start, stop, num }",
        ));
    }
    let values = match &a.values {
        Some(v) => listed_values(field, &keys, v, bad)?,
        None => spaced_values(field, &keys, a, bad)?,
    };
    for (j, row) in values.iter().enumerate() {
        for (k, v) in keys.iter().zip(row) {
            if matches!(
                v,
                toml::Value::Array(_) | toml::Value::Table(_) | toml::Value::Datetime(_)
            ) {
                return Err(bad.field(
                    &format!("{field}.values[{j}]"),
                    v,
                    &format!("a number, string or boolean for {k}"),
                ));
            }
        }
    }
    column_type(&keys, &values)
        .map_err(|(k, why)| bad.field(&format!("{field} ({k})"), &"values", &why))?;
    Ok(Axis { keys, values })
}

/// An axis's `values = [...]`: one value per position for one key, an array of one value per
/// key for zipped keys.
fn listed_values(
    field: &str,
    keys: &[String],
    v: &[toml::Value],
    bad: &Bad,
) -> Result<Vec<Vec<toml::Value>>, PlanError> {
    if v.is_empty() {
        return Err(bad.field(&format!("{field}.values"), &"[]", "at least one value"));
    }
    if keys.len() == 1 {
        return Ok(v.iter().map(|x| vec![x.clone()]).collect());
    }
    let mut out = Vec::new();
    for (j, x) in v.iter().enumerate() {
        match x {
            toml::Value::Array(t) if t.len() == keys.len() => out.push(t.clone()),
            _ => {
                return Err(bad.field(
                    &format!("{field}.values[{j}]"),
                    x,
                    &format!(
                        "an array of {} values, one for each of keys = {keys:?}",
                        keys.len()
                    ),
                ))
            }
        }
    }
    Ok(out)
}

/// An axis's `linspace` or `logspace` (one key only).
fn spaced_values(
    field: &str,
    keys: &[String],
    a: &RawAxis,
    bad: &Bad,
) -> Result<Vec<Vec<toml::Value>>, PlanError> {
    if keys.len() != 1 {
        return Err(bad.field(
            field,
            &"linspace/logspace with several keys",
            "values = [[...], ...] for zipped keys",
        ));
    }
    let (r, log, what) = match (&a.linspace, &a.logspace) {
        (Some(r), _) => (*r, false, "linspace"),
        (_, Some(r)) => (*r, true, "logspace"),
        _ => unreachable!("one of them is given"),
    };
    let f = format!("{field}.{what}");
    Ok(spaced(r, log)
        .map_err(|(sub, v, why)| bad.field(&format!("{f}.{sub}"), &v, &why))?
        .into_iter()
        .map(|x| vec![toml::Value::Float(x)])
        .collect())
}

/// What the plan evaluates: the plant, models (each at most once, in the table's order) and a
/// policy (registered, its parameters checked by the policy).
pub(super) fn evaluation(e: &RawEvaluate, bad: &Bad) -> Result<Evaluate, PlanError> {
    let mut models = Vec::new();
    for m in MODELS {
        if e.models.iter().any(|x| x == m) {
            models.push(m.to_string());
        }
    }
    for m in &e.models {
        if !MODELS.contains(&m.as_str()) {
            return Err(bad.field("evaluate.models", m, &format!("a list of {MODELS:?}")));
        }
    }
    if models.len() != e.models.len() {
        return Err(bad.field(
            "evaluate.models",
            &format!("{:?}", e.models),
            "each model at most once",
        ));
    }
    let policy = e.policy.as_ref().map(|p| policy(p, bad)).transpose()?;
    if !e.plant && models.is_empty() && policy.is_none() {
        return Err(bad.field(
            "evaluate",
            &"nothing",
            "plant = true, models = [...] and/or policy = { name = ... }",
        ));
    }
    Ok(Evaluate {
        plant: e.plant,
        convergence: e.plant && e.convergence,
        models,
        policy,
    })
}

/// The plan's policy: a registered name and parameters it accepts.
fn policy(p: &RawPolicy, bad: &Bad) -> Result<PolicySpec, PlanError> {
    let mut params = Vec::new();
    for (k, v) in &p.params {
        let value = param_value(k, v)
            .map_err(|allowed| bad.field(&format!("evaluate.policy.params.{k}"), v, &allowed))?;
        params.push(format!("{k}={value}"));
    }
    let parsed = Params::parse(&params).map_err(|e| {
        bad.field(
            "evaluate.policy.params",
            &format!("{params:?}"),
            &e.to_string(),
        )
    })?;
    crawler_policies::lookup(&p.name)
        .map_err(|e| bad.field("evaluate.policy.name", &p.name, &e.to_string()))?;
    crawler_policies::check(&p.name, &parsed).map_err(|e| {
        bad.field(
            "evaluate.policy.params",
            &format!("{params:?}"),
            &e.to_string(),
        )
    })?;
    Ok(PolicySpec {
        name: p.name.clone(),
        params,
    })
}

/// The metrics kept: all without a list, else those listed, in the metric table's order.
pub(super) fn chosen_metrics(list: Option<&[String]>, bad: &Bad) -> Result<Vec<Metric>, PlanError> {
    let metrics: Vec<Metric> = match list {
        None => Metric::ALL.to_vec(),
        Some(list) => {
            let mut chosen = Vec::new();
            for m in list {
                let all = Metric::ALL.map(Metric::name).join(", ");
                chosen.push(
                    Metric::parse(m)
                        .ok_or_else(|| bad.field("metrics", m, &format!("a list of {all}")))?,
                );
            }
            // file order does not matter: the columns follow the metric table
            Metric::ALL
                .into_iter()
                .filter(|m| chosen.contains(m))
                .collect()
        }
    };
    if metrics.is_empty() {
        return Err(bad.field("metrics", &"[]", "at least one metric"));
    }
    Ok(metrics)
}

/// The map figures' keys are axes' keys, and a map has a plant and a model to compare.
pub(super) fn check_figures(
    f: &MapFigures,
    axes: &[Axis],
    evaluate: &Evaluate,
    bad: &Bad,
) -> Result<(), PlanError> {
    let axis_keys: Vec<&String> = axes.iter().flat_map(|a| a.keys.iter()).collect();
    for (field, k) in [
        ("figures.x", Some(&f.x)),
        ("figures.y", Some(&f.y)),
        ("figures.rows", f.rows.as_ref()),
        ("figures.columns", f.columns.as_ref()),
    ] {
        if let Some(k) = k {
            if !axis_keys.contains(&k) {
                return Err(bad.field(field, k, "the key of one of the plan's axes"));
            }
        }
    }
    if !evaluate.plant || evaluate.models.is_empty() {
        return Err(bad.field(
            "figures",
            &"a map",
            "maps compare models with the plant: evaluate.plant = true and at least one model",
        ));
    }
    Ok(())
}
