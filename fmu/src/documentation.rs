//! `documentation/index.html` of the FMUs, generated from the same model description.

use crawler_physics::model_description::{
    Causality, ModelDescription, Start, VarType, FMI2_ARRAY_STRIDE,
};

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn start_text(v: &crawler_physics::model_description::Variable) -> String {
    match &v.start {
        None => String::new(),
        Some(Start::Float(x)) => format!("{x:e}"),
        Some(Start::UInt(n)) => n.to_string(),
        Some(Start::Enum(n)) => n.to_string(),
        Some(Start::Text(t)) => t.clone(),
    }
}

/// The documentation page for the FMI `version` (2 or 3) FMU described by `md`.
pub fn index_html(md: &ModelDescription, version: u8) -> String {
    let n = md.variables.iter().find_map(|v| v.size).unwrap_or_default();
    let mut rows = String::new();
    for v in &md.variables {
        let name = match (v.size, version) {
            (Some(n), 2) => format!("{}[1] .. {}[{n}]", v.name, v.name),
            (Some(n), _) => format!("{}[{n}]", v.name),
            (None, _) => v.name.to_string(),
        };
        let reference = match (v.size, version) {
            (Some(_), 2) => format!("{} + i - 1", v.value_reference * FMI2_ARRAY_STRIDE),
            _ => v.value_reference.to_string(),
        };
        let ty = match (v.var_type, version) {
            (VarType::Float64, 2) => "Real",
            (VarType::UInt64, 2) => "Integer",
            (VarType::Enumeration, 2) => "Enumeration (Integer)",
            (VarType::Enumeration, _) => "Enumeration (Int64)",
            (t, _) => match t {
                VarType::Float64 => "Float64",
                VarType::UInt64 => "UInt64",
                VarType::Boolean => "Boolean",
                VarType::String => "String",
                VarType::Enumeration => "Enumeration",
            },
        };
        let causality = match (v.causality, version) {
            (Causality::StructuralParameter, 2) => "parameter".to_string(),
            (c, _) => serde_json::to_value(c)
                .ok()
                .and_then(|j| j.as_str().map(str::to_string))
                .unwrap_or_default(),
        };
        rows.push_str(&format!(
            "<tr><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td><code>{}</code></td><td>{}</td></tr>\n",
            escape(&name),
            reference,
            ty,
            causality,
            escape(v.unit),
            escape(&start_text(v)),
            escape(v.description)
        ));
    }
    let h = md.fixed_internal_step_size;
    let stop = md.default_experiment.map(|e| e.stop_time).unwrap_or(0.0);
    let arrays = if version == 2 {
        format!(
            "FMI 2.0 has no arrays: every array is the scalars <code>name[1]</code> .. <code>name[{n}]</code>, \
             with value reference <code>{FMI2_ARRAY_STRIDE} &times; (array's reference) + i - 1</code>. \
             N = {n} is fixed in this FMU."
        )
    } else {
        format!(
            "Arrays have <code>cells</code> = {n} values (a <code>Dimension</code> given by the structural parameter \
             <code>cells</code>, which, like <code>boundary</code>, is set in Configuration Mode or right after instantiation)."
        )
    };
    format!(
        r#"<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>crawler_physics: soft-crawler plant (FMI {version}.0 co-simulation)</title>
<style>body{{font-family:sans-serif;max-width:70em;margin:2em auto;line-height:1.4}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;vertical-align:top}}code{{font-size:90%}}</style></head>
<body>
<h1>crawler_physics: soft peristaltic crawler in a pipe</h1>
<p>{description}. Finite differences of <code>rho u_tt = A_c E u_xx + (A_m f)_x - c_v u_t - eps c_d (s - n_F)</code>,
<code>s</code> in Sgn(u_t) (set-valued: true stick at zero speed), solved per node in closed form at every internal step.
FMI {version}.0 co-simulation; instantiation token / GUID <code>{token}</code>.</p>
<h2>Use</h2>
<ul>
<li>Fixed communication step <b>H = {h:e} s</b> (a whole number of internal steps at Courant number 1).
Every <code>doStep</code> must cover a whole number of H (within 1e-9 (|t| + H)); any other step size is an Error.</li>
<li>By default the plant is driven by the paper's travelling wave (<code>actuation_mode = 1</code> and the <code>wave_*</code> inputs' start values).
Set <code>actuation_mode = 2</code> and <code>muscle_force</code> for a general muscle-force field, 0 for none.
Inputs are held over each step; a travelling wave is evaluated continuously inside it.</li>
<li>The default experiment runs to {stop:e} s, the first communication point at or after 10 s.</li>
<li>{arrays}</li>
<li>Parameters are set after instantiation or in initialisation mode; the steady metrics (<code>velocity</code>, <code>power</code>, ...) average whole
forcing periods after <code>settle</code> seconds and are 0 until <code>steady_periods</code> &gt; 0.</li>
<li><code>pipe</code> holds the friction map along the pipe as the JSON of a scenario's <code>[pipe]</code> section, e.g.
<code>{{"features":[{{"kind":"patch","from":0.5,"to":1.0,"eps":0.3}}]}}</code>.</li>
<li>The FMU state can be got, set, serialised and deserialised (restoring continues bit-identically).</li>
</ul>
<h2>Variables</h2>
<table>
<tr><th>name</th><th>value reference</th><th>type</th><th>causality</th><th>unit</th><th>start</th><th>description</th></tr>
{rows}</table>
</body>
</html>
"#,
        description = escape(md.description),
        token = escape(&md.instantiation_token),
    )
}
