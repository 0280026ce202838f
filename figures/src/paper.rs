//! `crawler-controller figures`: the paper's Fig. 5 and Fig. 6, paper model beside the improved model.
//!
//! Fig. 5: V and M against omega, k and f0, the others at the scenario's values, on the paper's
//! one-wavelength body. Where a model predicts backward motion its mileage is not drawn (the task's
//! mileage is distance forward per joule), and the ranges where a model is undefined or predicts
//! backward motion are shaded and named in the legend.
//!
//! Fig. 6: over the omega-k plane, (a) V at f0 = 1.5 N (the paper's unconstrained Fig. 6(a)) and
//! (b) the constrained optimal V with f0 chosen per cell by the optimiser (Fig. 6(b)), each with a
//! colour bar over its own range (so that the dependence of (b) on k alone shows as horizontal
//! bands), the resonance line `omega = k c`, the fastest or optimal point marked, and every cell
//! without a value coloured by its cause, named in the legend.
//!
//! Each figure is written as PNG and its data as CSV.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crawler_physics::scenario::Scenario;
use crawler_physics::wave::Wave;

use crawler_models::operating_point::OperatingPoint;
use crawler_models::optimizer::{
    linspace, parallel_map, Binding, BodyLength, GridSpec, Infeasibility, ModelChoice,
    OptimizeReport, Problem, DEFAULT_TIE_TOLERANCE,
};
use crawler_models::prediction::Prediction;

/// Grid sizes of the figures.
#[derive(Debug, Clone, Copy)]
pub struct FigureOptions {
    /// Points of each Fig. 5 sweep.
    pub sweep_points: usize,
    /// Points per axis of the Fig. 6 planes with the paper's model.
    pub plane_points: usize,
    /// Points per axis of the Fig. 6 planes with the improved model (each cell solves a periodic problem).
    pub plane_points_improved: usize,
    /// Plant runs per Fig. 5 sweep, drawn as points beside the models' curves (0: none).
    pub plant_points: usize,
}

impl Default for FigureOptions {
    fn default() -> Self {
        Self {
            sweep_points: 160,
            plane_points: 120,
            plane_points_improved: 36,
            plant_points: 6,
        }
    }
}

/// The amplitude of the paper's unconstrained Fig. 6(a), N.
const F0_FIG6A: f64 = 1.5;
/// Smallest amplitude of the Fig. 5 sweep in f0, N (log axis up to `limits.f0_max`).
const F0_SWEEP_MIN: f64 = 0.01;

const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
];

/// Registers a TrueType font for plot text (plotters draws text with it).
pub fn register_font() -> anyhow::Result<()> {
    let path = FONT_PATHS
        .iter()
        .find(|p| Path::new(p).is_file())
        .ok_or_else(|| {
            anyhow::anyhow!(
                "no TrueType font found for the plots (tried {}); install fonts-dejavu-core",
                FONT_PATHS.join(", ")
            )
        })?;
    let bytes: &'static [u8] = Box::leak(std::fs::read(path)?.into_boxed_slice());
    plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
        .map_err(|_| anyhow::anyhow!("cannot use the font {path}"))?;
    Ok(())
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

const PAPER: RGBColor = RGBColor(230, 120, 20);
const IMPROVED: RGBColor = RGBColor(30, 140, 70);

/// What a model says at one point of a figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// A forward speed: V and M are drawn.
    Forward,
    /// The model predicts `V <= 0`: V is drawn, the task's mileage is not defined.
    Backward,
    /// The model has no answer (the paper's `gamma = asin(z)` with `z > 1`, or no periodic solution).
    Undefined,
}

impl Status {
    /// The status of a prediction.
    pub fn of(p: &Prediction) -> Self {
        match p.velocity {
            Some(v) if v > 0.0 => Self::Forward,
            Some(_) => Self::Backward,
            None => Self::Undefined,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Forward => "forward",
            Self::Backward => "backward",
            Self::Undefined => "undefined",
        }
    }

    /// Mileage as the task counts it: only for forward motion.
    fn mileage(self, p: &Prediction) -> Option<f64> {
        (self == Self::Forward).then_some(p.mileage).flatten()
    }
}

/// What an undefined or backward prediction means for `model`, for legends.
fn status_label(model: &str, status: Status) -> String {
    match (model, status) {
        ("paper", Status::Undefined) => {
            "paper: undefined (asin argument > 1, body partly stuck)".into()
        }
        (_, Status::Undefined) => format!("{model}: no periodic solution"),
        (_, _) => format!("{model}: predicts V <= 0 (no mileage)"),
    }
}

fn models() -> [(&'static str, ModelChoice, RGBColor); 2] {
    [
        ("paper", ModelChoice::Paper, PAPER),
        (
            "improved",
            ModelChoice::parse("improved").expect("known model"),
            IMPROVED,
        ),
    ]
}

/// Writes `fig5.png`, `fig5_*.csv`, `fig6.png`, `fig6a.csv`, `fig6b.csv` into `out`; returns the files.
pub fn write_figures(
    scenario: &Scenario,
    out: &Path,
    opts: FigureOptions,
) -> anyhow::Result<Vec<PathBuf>> {
    anyhow::ensure!(
        opts.sweep_points >= 2 && opts.plane_points >= 2 && opts.plane_points_improved >= 2,
        "the figures need at least 2 points per axis"
    );
    register_font()?;
    std::fs::create_dir_all(out)?;
    let mut files = fig5(scenario, out, opts)?;
    files.extend(fig6(scenario, out, opts)?);
    Ok(files)
}

// ---------------------------------------------------------------------------------------------
// Fig. 5

/// One curve: label, colour and points (`None` where nothing is drawn).
struct Curve {
    label: String,
    color: RGBColor,
    points: Vec<(f64, Option<f64>)>,
}

/// A shaded range of x with its legend entry.
struct Band {
    label: String,
    color: RGBColor,
    ranges: Vec<(f64, f64)>,
}

/// A vertical reference line.
struct Marker {
    x: f64,
    label: String,
    color: RGBColor,
}

/// One Fig. 5 sweep.
struct Sweep<'a> {
    name: &'static str,
    axis: &'static str,
    xs: Vec<f64>,
    log_x: bool,
    wave_of: Box<dyn Fn(f64) -> Wave + Sync + 'a>,
    others: String,
    markers: Vec<Marker>,
}

/// The ranges of `xs` (sample edges half way, geometrically on a log axis) where `hit` holds.
fn ranges(xs: &[f64], log_x: bool, hit: impl Fn(usize) -> bool) -> Vec<(f64, f64)> {
    let mid = |a: f64, b: f64| if log_x { (a * b).sqrt() } else { 0.5 * (a + b) };
    let edge = |i: usize| -> f64 {
        if i == 0 {
            xs[0]
        } else if i == xs.len() {
            xs[xs.len() - 1]
        } else {
            mid(xs[i - 1], xs[i])
        }
    };
    let mut out = Vec::new();
    let mut start = None;
    for i in 0..=xs.len() {
        match (i < xs.len() && hit(i), start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push((edge(s), edge(i)));
                start = None;
            }
            _ => {}
        }
    }
    out
}

fn fig5(scenario: &Scenario, out: &Path, opts: FigureOptions) -> anyhow::Result<Vec<PathBuf>> {
    let base = OperatingPoint {
        wavelengths: 1.0,
        ..OperatingPoint::of(scenario)
    };
    let lim = scenario.limits;
    let w = base.wave;
    let c = base.body.wave_speed();
    let f0_lo = F0_SWEEP_MIN.min(0.5 * lim.f0_max);
    let log_f0: Vec<f64> = linspace(f0_lo.ln(), lim.f0_max.ln(), opts.sweep_points)
        .into_iter()
        .map(f64::exp)
        .collect();
    let scenario_marker = |x: f64| Marker {
        x,
        label: "the scenario's value".into(),
        color: RGBColor(90, 90, 90),
    };
    let sweeps = [
        Sweep {
            name: "omega",
            axis: "omega [rad/s]",
            xs: linspace(lim.omega[0], lim.omega[1], opts.sweep_points),
            log_x: false,
            wave_of: Box::new(move |x| Wave { omega: x, ..w }),
            others: format!("k = {:.2} rad/m, f0 = {} N", w.k, w.f0),
            markers: vec![
                scenario_marker(w.omega),
                Marker {
                    x: w.k * c,
                    label: "resonance omega_n = k c".into(),
                    color: BLACK,
                },
            ],
        },
        Sweep {
            name: "k",
            axis: "k [rad/m]",
            xs: linspace(lim.k[0], lim.k[1], opts.sweep_points),
            log_x: false,
            wave_of: Box::new(move |x| Wave { k: x, ..w }),
            others: format!("omega = {:.1} rad/s, f0 = {} N", w.omega, w.f0),
            markers: vec![
                scenario_marker(w.k),
                Marker {
                    x: w.omega / c,
                    label: "resonance k = omega / c".into(),
                    color: BLACK,
                },
            ],
        },
        Sweep {
            name: "f0",
            axis: "f0 [N] (log scale)",
            xs: log_f0,
            log_x: true,
            wave_of: Box::new(move |x| Wave { f0: x, ..w }),
            others: format!("omega = {:.1} rad/s, k = {:.2} rad/m", w.omega, w.k),
            markers: vec![scenario_marker(w.f0)],
        },
    ];
    let mut files = Vec::new();
    let png = out.join("fig5.png");
    {
        let root = BitMapBackend::new(&png, (2100, 1400)).into_drawing_area();
        root.fill(&WHITE)?;
        let (title, body) = root.split_vertically(50);
        let (body, legend) = body.split_vertically(1400 - 50 - 110);
        let mut entries: Vec<LegendEntry> = Vec::new();
        title.draw_text(
            &format!(
                "Fig. 5: speed V and mileage M = V / P on the one-wavelength body (eps = {}, n_F = {}); \
                 the other parameters at the scenario's values",
                base.friction.eps, base.friction.n_f
            ),
            &("sans-serif", 22).into_font().into(),
            (20, 15),
        )?;
        let panels = body.split_evenly((2, 3));
        for (col, sweep) in sweeps.iter().enumerate() {
            let preds: Vec<Vec<Prediction>> = models()
                .iter()
                .map(|(_, m, _)| {
                    parallel_map(&sweep.xs, |&x| {
                        m.predict(&base.with_wave((sweep.wave_of)(x)))
                    })
                })
                .collect();
            let status: Vec<Vec<Status>> = preds
                .iter()
                .map(|p| p.iter().map(Status::of).collect())
                .collect();
            let mut csv = format!(
                "{},V_paper,V_improved,M_paper,M_improved,status_paper,status_improved\n",
                sweep.name
            );
            let num = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
            for (i, x) in sweep.xs.iter().enumerate() {
                writeln!(
                    csv,
                    "{x},{},{},{},{},{},{}",
                    num(preds[0][i].velocity),
                    num(preds[1][i].velocity),
                    num(status[0][i].mileage(&preds[0][i])),
                    num(status[1][i].mileage(&preds[1][i])),
                    status[0][i].name(),
                    status[1][i].name()
                )?;
            }
            let path = out.join(format!("fig5_{}.csv", sweep.name));
            std::fs::write(&path, csv)?;
            files.push(path);
            let plant = plant_points(scenario, sweep, opts.plant_points)?;
            if !plant.is_empty() {
                let mut csv = format!("{},V_plant,M_plant\n", sweep.name);
                for (x, v, m) in &plant {
                    writeln!(csv, "{x},{},{}", num(*v), num(*m))?;
                }
                let path = out.join(format!("fig5_{}_plant.csv", sweep.name));
                std::fs::write(&path, csv)?;
                files.push(path);
            }
            let mut bands = Vec::new();
            for (m, (mname, _, color)) in models().iter().enumerate() {
                for (kind, shade) in [(Status::Undefined, 0.5), (Status::Backward, 0.3)] {
                    let r = ranges(&sweep.xs, sweep.log_x, |i| status[m][i] == kind);
                    if !r.is_empty() {
                        bands.push(Band {
                            label: status_label(mname, kind),
                            color: mix(*color, shade),
                            ranges: r,
                        });
                    }
                }
            }
            for (row, metric) in ["V [m/s]", "M [m/J] (log scale)"].iter().enumerate() {
                let curves: Vec<Curve> = models()
                    .iter()
                    .enumerate()
                    .map(|(m, (mname, _, color))| Curve {
                        label: format!("{mname} model"),
                        color: *color,
                        points: sweep
                            .xs
                            .iter()
                            .enumerate()
                            .map(|(i, &x)| {
                                let p = &preds[m][i];
                                (
                                    x,
                                    if row == 0 {
                                        p.velocity
                                    } else {
                                        status[m][i].mileage(p)
                                    },
                                )
                            })
                            .collect(),
                    })
                    .collect();
                let points: Vec<(f64, Option<f64>)> = plant
                    .iter()
                    .map(|&(x, v, m)| (x, if row == 0 { v } else { m }))
                    .collect();
                entries.extend(draw_sweep(
                    &panels[row * 3 + col],
                    &format!(
                        "{} vs {} ({})",
                        if row == 0 { "V" } else { "M" },
                        sweep.name,
                        sweep.others
                    ),
                    sweep.axis,
                    metric,
                    (sweep.log_x, row == 1),
                    &curves,
                    &bands,
                    &sweep.markers,
                    &points,
                )?);
            }
        }
        // one legend for the figure: every entry once
        let mut seen = std::collections::HashSet::new();
        entries.retain(|e| seen.insert(e.label.clone()));
        draw_legend(&legend, &entries)?;
        root.present()?;
    }
    files.push(png);
    Ok(files)
}

/// `color` mixed with white: `share` of the colour.
fn mix(color: RGBColor, share: f64) -> RGBColor {
    let m = |c: u8| (255.0 - share * (255.0 - f64::from(c))).round() as u8;
    RGBColor(m(color.0), m(color.1), m(color.2))
}

/// Draws one Fig. 5 panel. `log` is `(log x, log y)`; on a log y axis only positive values show.
#[allow(clippy::too_many_arguments)]
fn draw_sweep(
    area: &Area,
    title: &str,
    x_label: &str,
    y_label: &str,
    log: (bool, bool),
    curves: &[Curve],
    bands: &[Band],
    markers: &[Marker],
    plant: &[(f64, Option<f64>)],
) -> anyhow::Result<Vec<LegendEntry>> {
    let xs = curves.iter().flat_map(|c| c.points.iter().map(|p| p.0));
    let (x0, x1) = bounds(xs);
    // a little room at both ends, so that a marker at the sweep's end is not hidden by the axis
    let (x0, x1) = if log.0 {
        (x0 / 1.06, x1 * 1.06)
    } else {
        let pad = 0.02 * (x1 - x0);
        (x0 - pad, x1 + pad)
    };
    let ys = curves
        .iter()
        .flat_map(|c| c.points.iter().filter_map(|p| p.1))
        .chain(plant.iter().filter_map(|p| p.1))
        .filter(|&y| y.is_finite() && (!log.1 || y > 0.0));
    let (y0, y1) = bounds(ys);
    let (y0, y1) = if !y0.is_finite() {
        (0.0, 1.0)
    } else if log.1 {
        (y0 / 1.5, y1 * 1.5)
    } else {
        let (lo, hi) = (y0.min(0.0), y1.max(0.0));
        let pad = 0.06 * (hi - lo).max(1e-12);
        (lo - if y0 < 0.0 { pad } else { 0.0 }, hi + pad)
    };
    let (x_span, y_span) = if log.0 {
        (x0, y1 - y0)
    } else {
        (x1 - x0, y1 - y0)
    };
    let y_span = if log.1 { y0 } else { y_span };
    let main = area;
    let mut entries: Vec<LegendEntry> = Vec::new();
    macro_rules! panel {
        ($x:expr, $y:expr) => {{
            let mut chart = ChartBuilder::on(main)
                .caption(title, ("sans-serif", 21))
                .margin(14)
                .x_label_area_size(60)
                .y_label_area_size(104)
                .build_cartesian_2d($x, $y)?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(y_label)
                .x_labels(7)
                .y_labels(7)
                .label_style(("sans-serif", 20))
                .axis_desc_style(("sans-serif", 21))
                .y_label_formatter(&|v| tick(*v, y_span))
                .x_label_formatter(&|v| tick(*v, x_span))
                .draw()?;
            for b in bands {
                for &(a, z) in &b.ranges {
                    chart.draw_series(std::iter::once(Rectangle::new(
                        [(a, y0), (z, y1)],
                        b.color.filled(),
                    )))?;
                }
                entries.push(LegendEntry::patch(&b.label, b.color));
            }
            if !log.1 && y0 < 0.0 {
                chart.draw_series(LineSeries::new(
                    [(x0, 0.0), (x1, 0.0)],
                    BLACK.stroke_width(1),
                ))?;
            }
            for m in markers.iter().filter(|m| m.x >= x0 && m.x <= x1) {
                chart.draw_series(DashedLineSeries::new(
                    [(m.x, y0), (m.x, y1)],
                    6,
                    4,
                    m.color.stroke_width(1),
                ))?;
                entries.push(LegendEntry::dashed(&m.label, m.color));
            }
            for c in curves {
                let mut segment: Vec<(f64, f64)> = Vec::new();
                for &(x, y) in c.points.iter().chain(std::iter::once(&(f64::NAN, None))) {
                    match y.filter(|&y| !log.1 || y > 0.0) {
                        Some(y) => segment.push((x, y)),
                        None if !segment.is_empty() => {
                            chart.draw_series(LineSeries::new(
                                std::mem::take(&mut segment),
                                c.color.stroke_width(2),
                            ))?;
                        }
                        None => {}
                    }
                }
                entries.push(LegendEntry::line(&c.label, c.color));
            }
            let shown: Vec<(f64, f64)> = plant
                .iter()
                .filter_map(|&(x, y)| y.filter(|&y| !log.1 || y > 0.0).map(|y| (x, y)))
                .collect();
            if !shown.is_empty() {
                chart.draw_series(shown.iter().map(|&p| Circle::new(p, 7, WHITE.filled())))?;
                chart.draw_series(
                    shown
                        .iter()
                        .map(|&p| Circle::new(p, 7, PLANT.stroke_width(3))),
                )?;
                entries.push(LegendEntry::point(
                    "plant (simulated, steady window)",
                    PLANT,
                ));
            }
        }};
    }
    match log {
        (false, false) => panel!(x0..x1, y0..y1),
        (true, false) => panel!((x0..x1).log_scale(), y0..y1),
        (false, true) => panel!(x0..x1, (y0..y1).log_scale()),
        (true, true) => panel!((x0..x1).log_scale(), (y0..y1).log_scale()),
    }
    Ok(entries)
}

/// A plant point of Fig. 5: the swept value, V (m/s) and M (m/J).
type PlantPoint = (f64, Option<f64>, Option<f64>);

/// Colour of the plant's points in Fig. 5.
const PLANT: RGBColor = RGBColor(20, 20, 20);

/// The plant at `n` values of the sweep (evenly among its samples, the ends inside), on the
/// one-wavelength body the models assume, each at its wave's default Courant number: `(x, V, M)`.
fn plant_points(scenario: &Scenario, sweep: &Sweep, n: usize) -> anyhow::Result<Vec<PlantPoint>> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let m = sweep.xs.len();
    let xs: Vec<f64> = (0..n)
        .map(|i| sweep.xs[((2 * i + 1) * m / (2 * n)).min(m - 1)])
        .collect();
    let runs = parallel_map(
        &xs,
        |&x| -> anyhow::Result<(f64, Option<f64>, Option<f64>)> {
            let wave = (sweep.wave_of)(x);
            let mut s = scenario.with_wave(wave, Some(wave.wavelength()))?;
            s.plant.numerics.courant = crawler_physics::scenario::default_courant(s.alpha());
            let r = crawler_physics::simulate::simulate(
                &s,
                crawler_physics::simulate::SimulateOptions {
                    max_episodes: 0,
                    progress: None,
                },
            )?;
            let v = r.values();
            Ok((
                x,
                v.get(crawler_facts::Metric::Velocity),
                v.get(crawler_facts::Metric::Mileage)
                    .filter(|_| r.velocity > 0.0),
            ))
        },
    );
    runs.into_iter().collect()
}

/// An axis label: about three significant digits against the axis span, `0` for round-off
/// around zero, exponents only for very small or large numbers.
fn tick(v: f64, span: f64) -> String {
    if v.abs() <= 1e-9 * span {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.1e}");
        return s.replace(".0e", "e");
    }
    let decimals = (2.0 - span.min(a).log10().floor()).clamp(0.0, 6.0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    })
}

// ---------------------------------------------------------------------------------------------
// Legends drawn below a chart

/// One entry of a legend strip.
struct LegendEntry {
    label: String,
    color: RGBColor,
    kind: LegendKind,
}

#[derive(Clone, Copy, PartialEq)]
enum LegendKind {
    Patch,
    Line,
    Dashed,
    Point,
}

impl LegendEntry {
    fn patch(label: &str, color: RGBColor) -> Self {
        Self::new(label, color, LegendKind::Patch)
    }
    fn line(label: &str, color: RGBColor) -> Self {
        Self::new(label, color, LegendKind::Line)
    }
    fn dashed(label: &str, color: RGBColor) -> Self {
        Self::new(label, color, LegendKind::Dashed)
    }
    fn point(label: &str, color: RGBColor) -> Self {
        Self::new(label, color, LegendKind::Point)
    }
    fn new(label: &str, color: RGBColor, kind: LegendKind) -> Self {
        Self {
            label: label.to_string(),
            color,
            kind,
        }
    }
}

/// Draws `entries` left to right in rows inside `area`.
fn draw_legend(area: &Area, entries: &[LegendEntry]) -> anyhow::Result<()> {
    let (width, _) = area.dim_in_pixel();
    let style: TextStyle = ("sans-serif", 19).into_font().into();
    let (mut x, mut y) = (80i32, 4i32);
    let text_width = |t: &str| {
        area.estimate_text_size(t, &style)
            .map_or(10 * t.len() as u32, |s| s.0) as i32
    };
    // an entry longer than a row is split at its last space that fits, and the rest follows as
    // an entry of its own without a symbol
    let mut split: Vec<(Option<&LegendEntry>, String)> = Vec::new();
    for e in entries {
        let mut rest = e.label.clone();
        let mut first = true;
        while 80 + 52 + text_width(&rest) > width as i32 {
            let cut = rest
                .char_indices()
                .filter(|&(i, c)| c == ' ' && 80 + 52 + text_width(&rest[..i]) <= width as i32)
                .map(|(i, _)| i)
                .next_back();
            let Some(cut) = cut else { break };
            split.push((first.then_some(e), rest[..cut].to_string()));
            rest = rest[cut + 1..].to_string();
            first = false;
        }
        split.push((first.then_some(e), rest));
    }
    for (entry, label) in &split {
        let text_w = text_width(label);
        let w = 30 + text_w + 22;
        if x + w > width as i32 && x > 80 {
            x = 80;
            y += 28;
        }
        let Some(e) = entry else {
            area.draw_text(label, &style, (x + 30, y + 1))?;
            x += w;
            continue;
        };
        let cy = y + 11;
        match e.kind {
            LegendKind::Patch => area.draw(&Rectangle::new(
                [(x, cy - 7), (x + 22, cy + 7)],
                ShapeStyle::from(&e.color).filled(),
            ))?,
            LegendKind::Line => {
                if e.color == WHITE {
                    // a white line shows on the dark cells it separates
                    area.draw(&Rectangle::new(
                        [(x, cy - 7), (x + 22, cy + 7)],
                        RGBColor(68, 1, 84).filled(),
                    ))?;
                }
                area.draw(&PathElement::new(
                    vec![(x, cy), (x + 22, cy)],
                    e.color.stroke_width(3),
                ))?
            }
            LegendKind::Dashed => {
                for s in [0, 9, 18] {
                    area.draw(&PathElement::new(
                        vec![(x + s, cy), (x + s + 5, cy)],
                        e.color.stroke_width(2),
                    ))?;
                }
            }
            LegendKind::Point => {
                area.draw(&Circle::new((x + 11, cy), 7, WHITE.filled()))?;
                area.draw(&Circle::new((x + 11, cy), 7, e.color.stroke_width(3)))?;
            }
        }
        if e.kind == LegendKind::Patch {
            area.draw(&Rectangle::new(
                [(x, cy - 7), (x + 22, cy + 7)],
                RGBColor(120, 120, 120).stroke_width(1),
            ))?;
        }
        area.draw_text(label, &style, (x + 30, y + 1))?;
        x += w;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Fig. 6

/// A cell of an omega-k plane: a speed, or the index of the category that explains its absence.
#[derive(Debug, Clone, Copy)]
enum PlaneCell {
    Value(f64),
    Category(usize),
}

/// A category of cells without a speed.
struct Category {
    label: String,
    color: RGBColor,
}

/// One heatmap panel.
struct Plane<'a> {
    title: String,
    omegas: &'a [f64],
    ks: &'a [f64],
    cells: Vec<PlaneCell>,
    categories: Vec<Category>,
    /// A marked point `(omega, k)` and its legend text.
    mark: Option<((f64, f64), String)>,
    /// The wave speed, for the resonance line `omega = k c`.
    wave_speed: f64,
    /// The colour scale, m/s; speeds below it get its darkest colour (said in the legend).
    range: (f64, f64),
    /// Regions outlined in white and labelled: the region of each cell and the regions' names.
    regions: Option<(Vec<usize>, Vec<&'static str>)>,
}

/// The `q`-quantile of the speeds of `cells`.
fn quantile(cells: &[PlaneCell], q: f64) -> Option<f64> {
    let mut v: Vec<f64> = cells
        .iter()
        .filter_map(|c| match c {
            PlaneCell::Value(v) => Some(*v),
            PlaneCell::Category(_) => None,
        })
        .collect();
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[((v.len() - 1) as f64 * q).round() as usize])
}

/// Fill colours of the categories: pale and unsaturated, so they cannot be read as speeds.
fn infeasibility_color(i: Infeasibility) -> RGBColor {
    match i {
        Infeasibility::Mileage => RGBColor(200, 200, 200),
        Infeasibility::Stress => RGBColor(236, 214, 178),
        Infeasibility::Strain => RGBColor(196, 214, 236),
        Infeasibility::F0Max => RGBColor(224, 200, 236),
        Infeasibility::NoForwardMotion => RGBColor(246, 196, 196),
        Infeasibility::ModelUndefined => RGBColor(150, 150, 150),
    }
}

fn fig6(scenario: &Scenario, out: &Path, opts: FigureOptions) -> anyhow::Result<Vec<PathBuf>> {
    let base = OperatingPoint {
        wavelengths: 1.0,
        ..OperatingPoint::of(scenario)
    };
    let lim = scenario.limits;
    let problem = Problem {
        body: base.body,
        friction: base.friction,
        task: scenario.task,
        limits: lim,
        body_length: BodyLength::OneWavelength,
    };
    let png = out.join("fig6.png");
    let mut csv_a = String::from("omega,k,model,V_unconstrained_f0_1.5N,status\n");
    let mut csv_b = String::from("omega,k,model,f0,V,binding,infeasibility\n");
    {
        let root = BitMapBackend::new(&png, (2000, 1800)).into_drawing_area();
        root.fill(&WHITE)?;
        let (title, body) = root.split_vertically(50);
        title.draw_text(
            &format!(
                "Fig. 6 on the one-wavelength body: (a) V at f0 = {F0_FIG6A} N, (b) constrained optimal V \
                 (M >= D/J0 = {:.3} m/J, sigma <= {} kPa, strain <= {}, f0 <= {} N)",
                scenario.task.min_mileage(),
                scenario.task.sigma_max / 1e3,
                lim.strain_max,
                lim.f0_max
            ),
            &("sans-serif", 22).into_font().into(),
            (20, 15),
        )?;
        let panels = body.split_evenly((2, 2));
        for (col, (mname, model, _)) in models().iter().enumerate() {
            let n = if matches!(model, ModelChoice::Paper) {
                opts.plane_points
            } else {
                opts.plane_points_improved
            };
            let omegas = linspace(lim.omega[0], lim.omega[1], n);
            let ks = linspace(lim.k[0], lim.k[1], n);
            let points: Vec<(f64, f64)> = ks
                .iter()
                .flat_map(|&k| omegas.iter().map(move |&w| (w, k)))
                .collect();
            // (a) unconstrained
            let preds: Vec<Prediction> = parallel_map(&points, |&(w, k)| {
                model.predict(&base.with_wave(Wave {
                    f0: F0_FIG6A,
                    k,
                    omega: w,
                    phase: 0.0,
                }))
            });
            let kinds = [Status::Backward, Status::Undefined];
            let mut cells = Vec::with_capacity(points.len());
            for ((w, k), p) in points.iter().zip(&preds) {
                let status = Status::of(p);
                writeln!(
                    csv_a,
                    "{w},{k},{mname},{},{}",
                    p.velocity.map_or(String::new(), |v| format!("{v:e}")),
                    status.name()
                )?;
                cells.push(match status {
                    Status::Forward => PlaneCell::Value(p.velocity.unwrap_or(0.0)),
                    other => {
                        PlaneCell::Category(kinds.iter().position(|&s| s == other).unwrap_or(0))
                    }
                });
            }
            let cells_a = cells;
            let fastest = points
                .iter()
                .zip(&cells_a)
                .filter_map(|(&pt, c)| match c {
                    PlaneCell::Value(v) => Some((pt, *v)),
                    PlaneCell::Category(_) => None,
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            draw_plane(
                &panels[col],
                &Plane {
                    title: format!("(a) V at f0 = {F0_FIG6A} N, {mname} model"),
                    omegas: &omegas,
                    ks: &ks,
                    categories: vec![
                        Category {
                            label: "V <= 0 predicted (backward)".into(),
                            color: infeasibility_color(Infeasibility::NoForwardMotion),
                        },
                        Category {
                            label: if *mname == "paper" {
                                "undefined: asin argument > 1 (partly stuck)".into()
                            } else {
                                "no periodic solution".into()
                            },
                            color: infeasibility_color(Infeasibility::ModelUndefined),
                        },
                    ],
                    mark: fastest.map(|((w, k), v)| {
                        (
                            (w, k),
                            format!(
                                "fastest: V = {v:.4} m/s at omega = {w:.1} rad/s, k = {k:.2} rad/m"
                            ),
                        )
                    }),
                    wave_speed: base.body.wave_speed(),
                    // the lowest tenth of the speeds (slow waves far below resonance) below the
                    // scale, so that the ridge along resonance shows
                    range: (
                        quantile(&cells_a, 0.1).unwrap_or(0.0),
                        fastest.map_or(1.0, |f| f.1),
                    ),
                    regions: None,
                    cells: cells_a,
                },
            )?;
            // (b) constrained optimum per cell
            let report = problem.optimize(
                model,
                &GridSpec {
                    omega_points: n,
                    k_points: n,
                    refine: true,
                    tie_tolerance: DEFAULT_TIE_TOLERANCE,
                },
            );
            let plane_b = match &report {
                Ok(r) => {
                    for cell in &r.cells {
                        writeln!(
                            csv_b,
                            "{},{},{mname},{},{},{:?},{}",
                            cell.omega,
                            cell.k,
                            cell.f0.map_or(String::new(), |v| format!("{v:e}")),
                            cell.velocity.map_or(String::new(), |v| format!("{v:e}")),
                            cell.binding,
                            cell.infeasibility.map_or("", |i| i.describe())
                        )?;
                    }
                    constrained_plane(mname, r, &omegas, &ks, base.body.wave_speed())
                }
                Err(e) => Plane {
                    title: format!("(b) constrained optimal V, {mname} model: {e}"),
                    omegas: &omegas,
                    ks: &ks,
                    cells: vec![PlaneCell::Category(0); points.len()],
                    categories: vec![Category {
                        label: "infeasible".into(),
                        color: infeasibility_color(Infeasibility::Mileage),
                    }],
                    mark: None,
                    wave_speed: base.body.wave_speed(),
                    range: (0.0, 1.0),
                    regions: None,
                },
            };
            draw_plane(&panels[2 + col], &plane_b)?;
        }
        root.present()?;
    }
    let mut files = Vec::new();
    for (name, csv) in [("fig6a.csv", csv_a), ("fig6b.csv", csv_b)] {
        let path = out.join(name);
        std::fs::write(&path, csv)?;
        files.push(path);
    }
    files.push(png);
    Ok(files)
}

/// The colour scale of a Fig. 6(b) panel, m/s: from the slowest cell where the budget binds to
/// the fastest cell. The budget's cells, whose speed depends on `k` alone, differ by about 2 %
/// (paper's parameters); a scale from 0 would paint them all in its top colour. Slower cells
/// (where the strain limit binds) get the darkest colour, and the legend says so.
fn constrained_colour_range(cells: &[crawler_models::optimizer::Cell]) -> (f64, f64) {
    let budget = cells
        .iter()
        .filter(|c| c.binding == Binding::Mileage)
        .filter_map(|c| c.velocity);
    let (lo, hi) = bounds(budget);
    let top = cells
        .iter()
        .filter_map(|c| c.velocity)
        .fold(f64::NEG_INFINITY, f64::max);
    if lo.is_finite() {
        (lo, top.max(hi))
    } else {
        bounds(cells.iter().filter_map(|c| c.velocity))
    }
}

/// The Fig. 6(b) panel of an optimiser report.
fn constrained_plane<'a>(
    mname: &str,
    r: &OptimizeReport,
    omegas: &'a [f64],
    ks: &'a [f64],
    wave_speed: f64,
) -> Plane<'a> {
    let present: Vec<Infeasibility> = Infeasibility::ALL
        .into_iter()
        .filter(|i| r.cells.iter().any(|c| c.infeasibility == Some(*i)))
        .collect();
    let cells = r
        .cells
        .iter()
        .map(|c| match (c.velocity, c.infeasibility) {
            (Some(v), _) => PlaneCell::Value(v),
            (None, Some(i)) => {
                PlaneCell::Category(present.iter().position(|&p| p == i).unwrap_or(0))
            }
            (None, None) => PlaneCell::Category(0),
        })
        .collect();
    let o = &r.optimum;
    let t = &r.tie_break;
    let range = constrained_colour_range(&r.cells);
    let names = [
        "budget M = D/J0 binds",
        "stress limit binds",
        "strain limit binds",
        "f0_max binds",
        "infeasible",
    ];
    let region = r
        .cells
        .iter()
        .map(|c| match c.binding {
            Binding::Mileage => 0,
            Binding::Stress => 1,
            Binding::Strain => 2,
            Binding::F0Max => 3,
            Binding::Infeasible => 4,
        })
        .collect();
    Plane {
        title: format!("(b) constrained optimal V, {mname} model"),
        omegas,
        ks,
        cells,
        categories: present
            .iter()
            .map(|&i| Category {
                label: format!("infeasible: {}", i.describe()),
                color: infeasibility_color(i),
            })
            .collect(),
        mark: Some((
            (o.omega, o.k),
            format!(
                "optimum: V = {:.4} m/s, f0 = {:.3} N at omega = {:.1} rad/s, k = {:.2} rad/m \
                 (lowest f0 of {} cells within {} % of the fastest)",
                o.prediction.velocity.unwrap_or(0.0),
                o.f0,
                o.omega,
                o.k,
                t.tied_cells,
                100.0 * t.tolerance
            ),
        )),
        wave_speed,
        range,
        regions: Some((region, names.to_vec())),
    }
}

/// Draws a heatmap with its colour bar (own range, m/s), the resonance line, the mark and a
/// legend of the categories below.
fn draw_plane(area: &Area, plane: &Plane) -> anyhow::Result<()> {
    let (omegas, ks) = (plane.omegas, plane.ks);
    let (w0, w1) = (omegas[0], omegas[omegas.len() - 1]);
    let (k0, k1) = (ks[0], ks[ks.len() - 1]);
    let dw = (w1 - w0) / (omegas.len() - 1).max(1) as f64;
    let dk = (k1 - k0) / (ks.len() - 1).max(1) as f64;
    let (vmin, vmax) = plane.range;
    let below = plane
        .cells
        .iter()
        .any(|c| matches!(c, PlaneCell::Value(v) if *v < vmin));
    let (vmin, vmax) = if !vmin.is_finite() || !vmax.is_finite() {
        (0.0, 1.0)
    } else if vmax - vmin <= 1e-9 * vmax.abs().max(1e-300) {
        // a flat panel: a small symmetric range, so the one colour sits mid-scale
        let d = 1e-6 * vmax.abs().max(1e-12);
        (vmin - d, vmax + d)
    } else {
        (vmin, vmax)
    };
    let cmap = &plotters::style::colors::colormaps::ViridisRGB;
    let color_of = |v: f64| cmap.get_color(((v - vmin) / (vmax - vmin)).clamp(0.0, 1.0));
    let (h, legend_h) = (area.dim_in_pixel().1, 120);
    let (top, legend) = area.split_vertically(h - legend_h);
    let (w, _) = top.dim_in_pixel();
    let (main, bar) = top.split_horizontally(w - 215);
    // the plotted range: the cells, and room for the mark's circle where it sits on an edge
    let (mut xr, mut yr) = (
        (w0 - 0.5 * dw, w1 + 0.5 * dw),
        (k0 - 0.5 * dk, k1 + 0.5 * dk),
    );
    if let Some(((w, k), _)) = &plane.mark {
        let room = |(lo, hi): (f64, f64), v: f64| {
            let pad = 0.05 * (hi - lo);
            (lo.min(v - pad), hi.max(v + pad))
        };
        xr = room(xr, *w);
        yr = room(yr, *k);
    }
    let mut chart = ChartBuilder::on(&main)
        .caption(&plane.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(56)
        .y_label_area_size(80)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("omega [rad/s]")
        .y_desc("k [rad/m]")
        .x_labels(6)
        .y_labels(6)
        .label_style(("sans-serif", 19))
        .axis_desc_style(("sans-serif", 20))
        .x_label_formatter(&|v| tick(*v, w1 - w0))
        .y_label_formatter(&|v| tick(*v, k1 - k0))
        .draw()?;
    chart.draw_series(ks.iter().enumerate().flat_map(|(j, &k)| {
        omegas.iter().enumerate().map(move |(i, &w)| {
            let color = match plane.cells[j * omegas.len() + i] {
                PlaneCell::Value(v) => color_of(v),
                PlaneCell::Category(c) => plane.categories[c].color,
            };
            Rectangle::new(
                [(w - 0.5 * dw, k - 0.5 * dk), (w + 0.5 * dw, k + 0.5 * dk)],
                color.filled(),
            )
        })
    }))?;
    // resonance: omega = k c
    let c = plane.wave_speed;
    let line: Vec<(f64, f64)> = linspace(k0, k1, 200)
        .into_iter()
        .map(|k| (k * c, k))
        .filter(|&(w, _)| w >= w0 - 0.5 * dw && w <= w1 + 0.5 * dw)
        .collect();
    if line.len() > 1 {
        chart.draw_series(LineSeries::new(line, BLACK.stroke_width(2)))?;
    }
    if let Some((region, names)) = &plane.regions {
        draw_regions(&mut chart, omegas, ks, region, names)?;
    }
    let mut entries: Vec<LegendEntry> = plane
        .categories
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            plane
                .cells
                .iter()
                .any(|c| matches!(c, PlaneCell::Category(j) if j == i))
        })
        .map(|(_, cat)| LegendEntry::patch(&cat.label, cat.color))
        .collect();
    if below {
        entries.push(LegendEntry::patch(
            &format!(
                "V below the colour scale (< {} m/s)",
                tick(vmin, vmax - vmin)
            ),
            color_of(vmin),
        ));
    }
    entries.push(LegendEntry::line("resonance omega = k c", BLACK));
    if plane.regions.is_some() {
        entries.push(LegendEntry::line(
            "where the binding constraint changes",
            WHITE,
        ));
    }
    if let Some(((w, k), label)) = &plane.mark {
        chart.draw_series([
            Circle::new((*w, *k), 9, WHITE.filled()),
            Circle::new((*w, *k), 9, RGBColor(200, 0, 0).stroke_width(3)),
        ])?;
        entries.push(LegendEntry::point(label, RGBColor(200, 0, 0)));
    }
    draw_colour_bar(&bar, vmin, vmax, &color_of)?;
    draw_legend(&legend, &entries)
}

type PlaneChart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// Width of one character of a region's name (16 px sans-serif, generous), px.
const NAME_CHAR_PX: f64 = 9.5;

/// Outlines in white the regions of cells with equal `region`, and names each at its centre.
fn draw_regions(
    chart: &mut PlaneChart,
    omegas: &[f64],
    ks: &[f64],
    region: &[usize],
    names: &[&str],
) -> anyhow::Result<()> {
    let n = omegas.len();
    let dw = (omegas[n - 1] - omegas[0]) / (n - 1).max(1) as f64;
    let dk = (ks[ks.len() - 1] - ks[0]) / (ks.len() - 1).max(1) as f64;
    let mut edges = Vec::new();
    for j in 0..ks.len() {
        for i in 0..n {
            let r = region[j * n + i];
            let (w, k) = (omegas[i] + 0.5 * dw, ks[j] + 0.5 * dk);
            if i + 1 < n && region[j * n + i + 1] != r {
                edges.push([(w, k - dk), (w, k)]);
            }
            if j + 1 < ks.len() && region[(j + 1) * n + i] != r {
                edges.push([(w - dw, k), (w, k)]);
            }
        }
    }
    chart.draw_series(
        edges
            .into_iter()
            .map(|e| PathElement::new(e.to_vec(), WHITE.stroke_width(2))),
    )?;
    let x_range = chart.x_range();
    let w_per_px =
        (x_range.end - x_range.start) / chart.plotting_area().dim_in_pixel().0.max(1) as f64;
    for (id, name) in names.iter().enumerate() {
        let (mut sw, mut sk, mut count) = (0.0, 0.0, 0usize);
        for (c, &r) in region.iter().enumerate() {
            if r == id {
                sw += omegas[c % n];
                sk += ks[c / n];
                count += 1;
            }
        }
        if count * 150 < region.len() {
            continue; // too small a region to hold its name
        }
        // at the region's centre, moved inwards where the name would cross the plot's edge
        let half = 0.5 * NAME_CHAR_PX * name.chars().count() as f64 * w_per_px;
        let (lo, hi) = (x_range.start + half, x_range.end - half);
        let at = (
            (sw / count as f64).clamp(lo.min(hi), hi.max(lo)),
            sk / count as f64,
        );
        chart.draw_series(std::iter::once(Text::new(
            name.to_string(),
            at,
            ("sans-serif", 16)
                .into_font()
                .color(&WHITE)
                .pos(Pos::new(HPos::Center, VPos::Center)),
        )))?;
    }
    Ok(())
}

/// A vertical colour bar from `vmin` to `vmax`, labelled in m/s.
fn draw_colour_bar(
    area: &Area,
    vmin: f64,
    vmax: f64,
    color_of: &dyn Fn(f64) -> RGBColor,
) -> anyhow::Result<()> {
    let steps = 200;
    let dv = (vmax - vmin) / steps as f64;
    let mut chart = ChartBuilder::on(area)
        .margin_top(40)
        .margin_bottom(70)
        .margin_right(8)
        .y_label_area_size(120)
        .build_cartesian_2d(0.0..1.0, vmin..vmax)?;
    // each panel has its own range: say how wide it is, so that a narrow one is not read as a
    // strong dependence
    let span = if vmax.abs() > 0.0 {
        format!(
            "V [m/s], this panel's range ({:.1} % of its top)",
            100.0 * (vmax - vmin) / vmax.abs()
        )
    } else {
        "V [m/s], this panel's range".to_string()
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(span)
        .y_labels(8)
        .axis_desc_style(("sans-serif", 17))
        .label_style(("sans-serif", 17))
        .y_label_formatter(&|v| tick(*v, vmax - vmin))
        .draw()?;
    chart.draw_series((0..steps).map(|i| {
        let v = vmin + i as f64 * dv;
        Rectangle::new([(0.0, v), (1.0, v + dv)], color_of(v + 0.5 * dv).filled())
    }))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's Fig. 6(b) problem on a coarse grid, with the paper's model.
    fn paper_fig6b() -> OptimizeReport {
        let scenario = Scenario::paper();
        let base = OperatingPoint {
            wavelengths: 1.0,
            ..OperatingPoint::of(&scenario)
        };
        let problem = Problem {
            body: base.body,
            friction: base.friction,
            task: scenario.task,
            limits: scenario.limits,
            body_length: BodyLength::OneWavelength,
        };
        problem
            .optimize(
                &ModelChoice::Paper,
                &GridSpec {
                    omega_points: 24,
                    k_points: 24,
                    refine: false,
                    tie_tolerance: DEFAULT_TIE_TOLERANCE,
                },
            )
            .unwrap()
    }

    #[test]
    fn the_constrained_panel_shows_the_dependence_on_k() {
        // Where the budget binds, V depends on k alone and spans a few per cent: the colour
        // scale must resolve it, the shortest and the longest waves at opposite ends of the bar.
        let r = paper_fig6b();
        let (lo, hi) = constrained_colour_range(&r.cells);
        assert!(lo > 0.0 && hi > lo, "{lo} .. {hi}");
        let budget: Vec<_> = r
            .cells
            .iter()
            .filter(|c| c.binding == Binding::Mileage)
            .collect();
        assert!(budget.len() > r.cells.len() / 4, "{} cells", budget.len());
        let at = |c: &crawler_models::optimizer::Cell| (c.velocity.unwrap() - lo) / (hi - lo);
        let k_min = budget.iter().map(|c| c.k).fold(f64::INFINITY, f64::min);
        let k_max = budget.iter().map(|c| c.k).fold(f64::NEG_INFINITY, f64::max);
        for c in &budget {
            let t = at(c);
            assert!((0.0..=1.0 + 1e-12).contains(&t), "{t}");
            if c.k == k_min {
                assert!(t < 0.1, "longest wave at {t} of the bar");
            }
            if c.k == k_max {
                assert!(t > 0.9, "shortest wave at {t} of the bar");
            }
        }
        // and the panel marks the optimum the report chose
        let omegas = r.omega_grid.clone();
        let ks = r.k_grid.clone();
        let plane = constrained_plane("paper", &r, &omegas, &ks, 1.0);
        let ((w, k), label) = plane.mark.expect("the optimum is marked");
        assert_eq!((w, k), (r.optimum.omega, r.optimum.k));
        assert!(label.starts_with("optimum: V = "), "{label}");
        assert_eq!(plane.range, (lo, hi));
    }

    #[test]
    fn the_status_of_a_prediction_decides_whether_its_mileage_is_drawn() {
        let scenario = Scenario::paper();
        let base = OperatingPoint {
            wavelengths: 1.0,
            ..OperatingPoint::of(&scenario)
        };
        // far below resonance the paper's model predicts backward motion (docs/physics.md §3.2):
        // Fig. 5 must not draw a mileage there
        let slow = ModelChoice::Paper.predict(&base.with_wave(Wave {
            omega: 10.0,
            ..base.wave
        }));
        assert!(slow.velocity.unwrap() < 0.0, "{:?}", slow.velocity);
        assert_eq!(Status::of(&slow), Status::Backward);
        assert_eq!(Status::of(&slow).mileage(&slow), None);
        let fast = ModelChoice::Paper.predict(&base);
        assert_eq!(Status::of(&fast), Status::Forward);
        assert_eq!(Status::of(&fast).mileage(&fast), fast.mileage);
        assert!(fast.mileage.unwrap() > 0.0);
    }
}
