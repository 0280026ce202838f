//! The maps as a Rerun recording: one tensor per model and metric with its dimensions named after
//! the plan's axes (rows, columns, y, x), values in percent (NaN where undefined), the axes'
//! values as a text document, and the PNG figures beside them.

use std::path::Path;

use crawler_sweep::maps::{Grid, Maps};
use crawler_sweep::plan::Plan;

/// The tensor of a map: shape and dimension names from the axes, `scale` applied, NaN for
/// undefined values.
fn tensor(maps: &Maps, panels: &[Grid], scale: f64) -> rerun::Tensor {
    let mut shape = Vec::new();
    let mut names = Vec::new();
    if let Some(r) = &maps.rows {
        shape.push(r.values.len() as u64);
        names.push(r.key.clone());
    }
    if let Some(c) = &maps.columns {
        shape.push(c.values.len() as u64);
        names.push(c.key.clone());
    }
    shape.push(maps.y.values.len() as u64);
    names.push(maps.y.key.clone());
    shape.push(maps.x.values.len() as u64);
    names.push(maps.x.key.clone());
    let data: Vec<f32> = panels
        .iter()
        .flat_map(|g| g.iter().map(|v| v.map_or(f32::NAN, |x| (scale * x) as f32)))
        .collect();
    let t = rerun::TensorData::new(shape, rerun::datatypes::TensorBuffer::F32(data.into()));
    rerun::Tensor::new(t).with_dim_names(names)
}

fn axes_markdown(plan: &Plan, maps: &Maps) -> String {
    let mut s = format!(
        "# Sweep {}\n\n{}\n\nTensors under `maps/` hold the relative error of each model against the plant, \
         in percent (|model / plant - 1| x 100, signed; NaN: undefined); `plant/stuck_fraction` the plant's \
         stuck fraction; `plant/convergence` the estimated discretisation error in percent. \
         Their dimensions are named after the plan's axes:\n\n",
        plan.name, plan.description
    );
    for a in [
        &maps.rows,
        &maps.columns,
        &Some(maps.y.clone()),
        &Some(maps.x.clone()),
    ]
    .into_iter()
    .flatten()
    {
        let vals: Vec<String> = a.values.iter().map(|v| v.to_string()).collect();
        s += &format!(
            "- `{}` ({} values): {}\n",
            a.key,
            vals.len(),
            vals.join(", ")
        );
    }
    s
}

/// Writes the recording of `maps` (and the PNGs in the same folder, if present) to `path`.
pub fn write(plan: &Plan, maps: &Maps, path: &Path) -> anyhow::Result<()> {
    let cannot = |e: &dyn std::fmt::Display| {
        anyhow::anyhow!("cannot write recording {}: {e}", path.display())
    };
    let rec = rerun::RecordingStreamBuilder::new("crawler-sweep")
        .save(path)
        .map_err(|e| cannot(&e))?;
    rec.log_static(
        "axes",
        &rerun::TextDocument::from_markdown(axes_markdown(plan, maps)),
    )
    .map_err(|e| cannot(&e))?;
    for ((model, metric), panels) in &maps.errors {
        rec.log_static(
            format!("maps/{model}/{metric}"),
            &tensor(maps, panels, 100.0),
        )
        .map_err(|e| cannot(&e))?;
    }
    for model in &maps.models {
        rec.log_static(
            format!("maps/{model}/worst"),
            &tensor(maps, &maps.worst(model), 100.0),
        )
        .map_err(|e| cannot(&e))?;
        rec.log_static(
            format!("maps/{model}/valid"),
            &tensor(maps, &maps.valid[model], 1.0),
        )
        .map_err(|e| cannot(&e))?;
    }
    rec.log_static("plant/stuck_fraction", &tensor(maps, &maps.stuck, 1.0))
        .map_err(|e| cannot(&e))?;
    rec.log_static("plant/convergence", &tensor(maps, &maps.convergence, 100.0))
        .map_err(|e| cannot(&e))?;
    if let Some(dir) = path.parent() {
        let mut pngs: Vec<_> = std::fs::read_dir(dir)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "png"))
            .collect();
        pngs.sort();
        for p in pngs {
            let name = p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let img = rerun::EncodedImage::from_file(&p).map_err(|e| cannot(&e))?;
            rec.log_static(format!("figures/{name}"), &img)
                .map_err(|e| cannot(&e))?;
        }
    }
    rec.flush_blocking().map_err(|e| cannot(&e))?;
    Ok(())
}
