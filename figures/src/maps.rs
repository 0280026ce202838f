//! PNG heat maps of a plan's maps (plotters): one figure per model and metric (and the worst
//! metric), with a panel per (row, column) value, a logarithmic colour bar of the relative error,
//! contour lines at 1 %, 5 % and 20 %, and undefined cells in grey; the plant's stuck fraction
//! and its convergence estimate likewise.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;

use crate::contour::segments;
use crawler_sweep::maps::{short_name, Grid, Maps};
use crawler_sweep::plan::Plan;

/// Contour levels of the relative error, with their colours.
pub const LEVELS: [(f64, RGBColor, &str); 3] = [
    (0.01, WHITE, "white: 1 %"),
    (0.05, BLACK, "black: 5 %"),
    (0.20, RGBColor(230, 20, 20), "red: 20 %"),
];

/// Colour of undefined cells.
pub const UNDEFINED: RGBColor = RGBColor(200, 200, 200);

/// Colour of cells whose value is exactly zero on a logarithmic scale (a body that never sticks).
pub const ZERO: RGBColor = RGBColor(255, 255, 255);

/// Colour of the dashed line at the plant's Courant switch (`alpha = 1.1`).
pub const SWITCH: RGBColor = RGBColor(255, 140, 0);

/// How values map to colours.
#[derive(Debug, Clone, Copy)]
enum Scale {
    /// log10 |v| from `lo` to `hi` decades (values beyond are clamped); bar labels in percent.
    LogPercent { lo: f64, hi: f64 },
    /// log10 v of a share from `lo` to 0 decades, exact zeros in [`ZERO`]; labels in percent.
    LogShare { lo: f64 },
}

impl Scale {
    fn position(&self, v: f64) -> f64 {
        match *self {
            Scale::LogPercent { lo, hi } => {
                let l = v.abs().max(1e-300).log10();
                ((l - lo) / (hi - lo)).clamp(0.0, 1.0)
            }
            Scale::LogShare { lo } => Scale::LogPercent { lo, hi: 0.0 }.position(v),
        }
    }

    fn ticks(&self) -> Vec<(f64, String)> {
        match *self {
            Scale::LogPercent { lo, hi } => {
                let mut t = Vec::new();
                let mut d = lo.ceil() as i32;
                while d as f64 <= hi + 1e-9 {
                    let pct = 10f64.powi(d + 2);
                    let label = if pct >= 1.0 {
                        format!("{pct:.0} %")
                    } else {
                        format!("{} %", trim_pct(pct))
                    };
                    t.push(((d as f64 - lo) / (hi - lo), label));
                    d += 1;
                }
                if let Some(last) = t.last_mut() {
                    last.1 = format!(">= {}", last.1);
                }
                if let Some(first) = t.first_mut() {
                    first.1 = format!("<= {}", first.1);
                }
                t
            }
            Scale::LogShare { lo } => {
                let mut t = Scale::LogPercent { lo, hi: 0.0 }.ticks();
                if let Some(last) = t.last_mut() {
                    last.1 = "100 %".into();
                }
                t
            }
        }
    }
}

fn trim_pct(p: f64) -> String {
    let s = format!("{p:.4}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn color(scale: Scale, v: f64) -> RGBColor {
    if matches!(scale, Scale::LogShare { .. }) && v == 0.0 {
        return ZERO;
    }
    ViridisRGB.get_color(scale.position(v) as f32)
}

/// One figure: a title, a note under it, what each panel shows.
struct Figure<'a> {
    file: String,
    title: String,
    note: String,
    panels: &'a [Grid],
    scale: Scale,
    bar_label: &'a str,
    contours: bool,
    /// What a grey cell means, for the colour bar.
    undefined: &'a str,
}

/// Draws every figure of `maps` into `dir`; returns the files written.
pub fn draw(plan: &Plan, maps: &Maps, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    crate::paper::register_font()?;
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let err_scale = Scale::LogPercent { lo: -4.0, hi: 0.0 };
    let mut written = Vec::new();
    let worst: Vec<(String, Vec<Grid>)> = maps
        .models
        .iter()
        .map(|m| (m.clone(), maps.worst(m)))
        .collect();
    let mut figs: Vec<Figure> = Vec::new();
    for model in &maps.models {
        let undefined = if model == "paper" {
            "undefined: eps C0 / (R0 alpha) > 1"
        } else {
            "undefined: no periodic solution"
        };
        for &m in &maps.metrics {
            figs.push(Figure {
                file: format!("{}-{model}-{m}.png", plan.name),
                title: format!(
                    "{model} model: relative error of the {} against the plant",
                    m.info().label
                ),
                note: format!(
                    "|{model} / plant - 1|; contours {}; grey: {}",
                    level_note(),
                    why_undefined(model)
                ),
                panels: &maps.errors[&(model.clone(), m)],
                scale: err_scale,
                bar_label: "relative error",
                contours: true,
                undefined,
            });
        }
        let w = &worst.iter().find(|(n, _)| n == model).expect("a model").1;
        figs.push(Figure {
            file: format!("{}-{model}-worst.png", plan.name),
            title: format!(
                "{model} model: largest relative error of V, P, M and sigma against the plant"
            ),
            note: format!(
                "max over the metrics that have an error (a body at rest has no mileage); contours {}; grey: {}",
                level_note(),
                why_undefined(model)
            ),
            panels: w,
            scale: err_scale,
            bar_label: "relative error",
            contours: true,
            undefined,
        });
    }
    figs.push(Figure {
        file: format!("{}-plant-stuck-fraction.png", plan.name),
        title: "plant: stuck fraction (share of node-time at rest)".into(),
        note: "the plant's steady window at 2N cells, logarithmic; white: never sticks".into(),
        panels: &maps.stuck,
        scale: Scale::LogShare { lo: -4.0 },
        bar_label: "stuck fraction",
        contours: false,
        undefined: "undefined: no plant run",
    });
    figs.push(Figure {
        file: format!("{}-plant-convergence.png", plan.name),
        title: "plant: estimated discretisation error (N against 2N cells)".into(),
        note: format!(
            "largest over V, P, M and sigma of |value(2N) - value(N)| / |value(2N)|; contours {}; grey: withheld where N and 2N agree to round-off (the speed is quantised where the wave moves one cell per step) or the Courant number biases the stick statistics",
            level_note()
        ),
        panels: &maps.convergence,
        scale: err_scale,
        bar_label: "estimated error",
        contours: true,
        undefined: "not trusted or no run",
    });
    for f in &figs {
        let path = dir.join(&f.file);
        draw_figure(maps, f, &path)?;
        written.push(path);
    }
    Ok(written)
}

fn why_undefined(model: &str) -> &'static str {
    if model == "paper" {
        "undefined (eps C0 / (R0 alpha) > 1, no gamma: the body no longer slides back, it sticks)"
    } else {
        "undefined (no periodic solution found)"
    }
}

/// The note under a map's title, with the Courant switch's line explained when the x axis is
/// `alpha`: the plant's Courant number is 1 below `alpha = 1.1` and `1 / alpha` above, so its
/// values (and the errors against it) may step there.
fn notes(maps: &Maps, f: &Figure) -> Vec<String> {
    let mut lines: Vec<String> = f.note.split("; ").map(str::to_string).collect();
    if short_name(&maps.x.key) == "alpha" {
        lines.push(format!(
            "orange dashes: alpha = {}, where the plant's Courant number switches from 1 to 1/alpha (docs/numerics.md); the plant's values may step there",
            crawler_physics::scenario::SUPERSONIC_ALPHA
        ));
    }
    lines
}

fn level_note() -> String {
    LEVELS.iter().map(|l| l.2).collect::<Vec<_>>().join(", ")
}

fn axis_label(key: &str) -> String {
    match short_name(key).as_str() {
        "alpha" => "alpha = omega / omega_n".into(),
        "eps" => "eps (dry-friction coefficient)".into(),
        "f0" => "f0 (N)".into(),
        "k" => "k (rad/m)".into(),
        "omega" => "omega (rad/s)".into(),
        other => other.to_string(),
    }
}

/// Draws figure `f` of `maps` into the PNG file `path`: the title and notes, a panel per
/// (row, column) value and the colour bar.
fn draw_figure(maps: &Maps, f: &Figure, path: &Path) -> anyhow::Result<()> {
    let (nr, nc) = (maps.nrows(), maps.ncols());
    // sized so that the docs' width (about 900 px for three panels) keeps every label legible
    let (pw, ph) = (480u32, 400u32);
    let notes = notes(maps, f);
    let bar_w = 200u32;
    let head = 52 + 26 * notes.len() as u32;
    let size = (nc as u32 * pw + bar_w, nr as u32 * ph + head);
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, body) = root.split_vertically(head);
    top.draw(&Text::new(
        f.title.clone(),
        (14, 8),
        ("sans-serif", 30).into_font().color(&BLACK),
    ))?;
    for (i, line) in notes.iter().enumerate() {
        top.draw(&Text::new(
            line.clone(),
            (14, 48 + 26 * i as i32),
            ("sans-serif", 20).into_font().color(&RGBColor(60, 60, 60)),
        ))?;
    }
    let (grid_area, bar_area) = body.split_horizontally(nc as u32 * pw);
    let panels = grid_area.split_evenly((nr, nc));
    let cells = Cells::of(maps);
    for (pi, area) in panels.iter().enumerate() {
        draw_panel(maps, f, &cells, pi, area)?;
    }
    draw_colour_bar(f, &bar_area)?;
    root.present()
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

/// The cells of a map: the x and y values of their centres and their edges, half way between
/// values and half a step beyond the ends (in the axes' units).
struct Cells {
    /// x of the cells' centres.
    xs: Vec<f64>,
    /// y of the cells' centres.
    ys: Vec<f64>,
    /// x of the cells' edges, one more than `xs`.
    ex: Vec<f64>,
    /// y of the cells' edges, one more than `ys`.
    ey: Vec<f64>,
}

impl Cells {
    /// The cells of `maps`' axes (numeric).
    fn of(maps: &Maps) -> Self {
        let xs: Vec<f64> = maps
            .x
            .numbers()
            .into_iter()
            .map(|v| v.expect("numeric"))
            .collect();
        let ys: Vec<f64> = maps
            .y
            .numbers()
            .into_iter()
            .map(|v| v.expect("numeric"))
            .collect();
        let (ex, ey) = (cell_edges(&xs), cell_edges(&ys));
        Self { xs, ys, ex, ey }
    }
}

/// Cell edges halfway between the values `v`, half a step beyond the ends (one value: a cell
/// one unit wide).
fn cell_edges(v: &[f64]) -> Vec<f64> {
    let n = v.len();
    if n == 1 {
        return vec![v[0] - 0.5, v[0] + 0.5];
    }
    let mut e = Vec::with_capacity(n + 1);
    e.push(v[0] - 0.5 * (v[1] - v[0]));
    for i in 0..n - 1 {
        e.push(0.5 * (v[i] + v[i + 1]));
    }
    e.push(v[n - 1] + 0.5 * (v[n - 1] - v[n - 2]));
    e
}

/// Draws panel `pi` of figure `f` (row-major over the maps' rows and columns) into `area`: its
/// cells, the Courant switch's line on an `alpha` axis, and the contours if the figure has them.
fn draw_panel(
    maps: &Maps,
    f: &Figure,
    cells: &Cells,
    pi: usize,
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
) -> anyhow::Result<()> {
    let nc = maps.ncols();
    let Cells { xs, ys, ex, ey } = cells;
    let (ir, ic) = (pi / nc, pi % nc);
    let caption = [
        maps.rows.as_ref().map(|a| a.label(ir)),
        maps.columns.as_ref().map(|a| a.label(ic)),
    ]
    .into_iter()
    .flatten()
    .collect::<Vec<_>>()
    .join(", ");
    let (x0, x1) = (ex[0].min(ex[ex.len() - 1]), ex[0].max(ex[ex.len() - 1]));
    let (y0, y1) = (ey[0].min(ey[ey.len() - 1]), ey[0].max(ey[ey.len() - 1]));
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 22))
        .margin(8)
        .x_label_area_size(52)
        .y_label_area_size(62)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(axis_label(&maps.x.key))
        .y_desc(axis_label(&maps.y.key))
        .x_labels(6)
        .y_labels(6)
        .label_style(("sans-serif", 18))
        .axis_desc_style(("sans-serif", 19))
        .draw()?;
    let grid = &f.panels[pi];
    let nx = xs.len();
    chart.draw_series((0..ys.len()).flat_map(|iy| {
        (0..nx).map(move |ix| {
            let c = match grid[iy * nx + ix] {
                Some(v) => color(f.scale, v),
                None => UNDEFINED,
            };
            Rectangle::new([(ex[ix], ey[iy]), (ex[ix + 1], ey[iy + 1])], c.filled())
        })
    }))?;
    let switch = crawler_physics::scenario::SUPERSONIC_ALPHA;
    if short_name(&maps.x.key) == "alpha" && x0 < switch && switch < x1 {
        chart.draw_series(DashedLineSeries::new(
            vec![(switch, y0), (switch, y1)],
            8,
            6,
            SWITCH.stroke_width(2),
        ))?;
    }
    if f.contours {
        let logs: Vec<Option<f64>> = grid
            .iter()
            .map(|v| v.map(|x| x.abs().max(1e-300).log10()))
            .collect();
        for (level, col, _) in LEVELS {
            for [a, b] in segments(xs, ys, &logs, level.log10()) {
                chart.draw_series(std::iter::once(PathElement::new(
                    vec![a, b],
                    col.stroke_width(2),
                )))?;
            }
        }
    }
    Ok(())
}

/// Draws the colour bar of figure `f` into `bar_area`, with its ticks, its label and a swatch
/// for every category the panels can show.
fn draw_colour_bar(
    f: &Figure,
    bar_area: &DrawingArea<BitMapBackend<'_>, Shift>,
) -> anyhow::Result<()> {
    let bar = bar_area.margin(80, 150, 16, 80);
    let (bw, bh) = bar.dim_in_pixel();
    let steps = 200;
    for i in 0..steps {
        let t = i as f64 / (steps - 1) as f64;
        let y_top = ((1.0 - (i + 1) as f64 / steps as f64) * bh as f64) as i32;
        let y_bot = ((1.0 - i as f64 / steps as f64) * bh as f64) as i32;
        bar.draw(&Rectangle::new(
            [(0, y_top), (28.min(bw as i32), y_bot)],
            ViridisRGB.get_color(t as f32).filled(),
        ))?;
    }
    bar.draw(&Rectangle::new(
        [(0, 0), (28, bh as i32)],
        BLACK.stroke_width(1),
    ))?;
    for (t, label) in f.scale.ticks() {
        let y = ((1.0 - t) * bh as f64) as i32;
        bar.draw(&PathElement::new(vec![(28, y), (34, y)], BLACK))?;
        bar.draw(&Text::new(
            label,
            (38, y - 9),
            ("sans-serif", 18).into_font(),
        ))?;
    }
    bar_area.draw(&Text::new(
        f.bar_label.to_string(),
        (16, 40),
        ("sans-serif", 19).into_font(),
    ))?;
    let mut swatches = vec![(UNDEFINED, f.undefined.to_string())];
    if matches!(f.scale, Scale::LogShare { .. }) {
        swatches.insert(0, (ZERO, "0: never sticks".to_string()));
    }
    // below the lowest tick's label, one block per category (drawn on the bar's whole column:
    // the bar's own area clips at its bottom)
    let (bx, mut y) = (16, 80 + bh as i32 + 24);
    for (c, label) in &swatches {
        bar_area.draw(&Rectangle::new([(bx, y), (bx + 28, y + 18)], c.filled()))?;
        bar_area.draw(&Rectangle::new(
            [(bx, y), (bx + 28, y + 18)],
            BLACK.stroke_width(1),
        ))?;
        for part in wrap(label, 14) {
            bar_area.draw(&Text::new(
                part,
                (bx + 36, y),
                ("sans-serif", 16).into_font(),
            ))?;
            y += 20;
        }
        y += 8;
    }
    Ok(())
}

/// Splits `text` at spaces into lines of at most about `width` characters.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for w in text.split(' ') {
        match lines.last_mut() {
            Some(l) if l.len() + 1 + w.len() <= width => {
                l.push(' ');
                l.push_str(w);
            }
            _ => lines.push(w.to_string()),
        }
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_error_scales_ends_say_that_values_beyond_them_are_clamped() {
        let t = Scale::LogPercent { lo: -4.0, hi: 0.0 }.ticks();
        assert_eq!(t.len(), 5);
        assert_eq!(t[0], (0.0, "<= 0.01 %".to_string()));
        assert_eq!(t[4], (1.0, ">= 100 %".to_string()));
    }

    #[test]
    fn the_stuck_fraction_is_logarithmic_and_zero_has_its_own_colour() {
        let s = Scale::LogShare { lo: -4.0 };
        let t = s.ticks();
        assert_eq!(t.last().unwrap().1, "100 %");
        // one decade per quarter of the bar: 0.1 % and 10 % are a half apart
        assert!((s.position(0.1) - s.position(0.001) - 0.5).abs() < 1e-12);
        assert_eq!(color(s, 0.0), ZERO);
        assert_ne!(color(s, 1e-4), ZERO);
        // on the error scale zero is the bottom of the bar (no error), not a category
        assert_eq!(
            color(Scale::LogPercent { lo: -4.0, hi: 0.0 }, 0.0),
            ViridisRGB.get_color(0.0)
        );
    }

    #[test]
    fn a_long_category_is_wrapped_at_spaces() {
        assert_eq!(
            wrap("undefined: eps C0 / (R0 alpha) > 1", 14),
            vec!["undefined: eps", "C0 / (R0", "alpha) > 1"]
        );
        assert_eq!(wrap("short", 14), vec!["short"]);
    }
}
