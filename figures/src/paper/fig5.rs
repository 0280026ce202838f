//! Fig. 5: V and M against omega, k and f0, the paper's model beside the improved model and the
//! plant's points, with the ranges where a model is undefined or predicts backward motion shaded.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::coord::CoordTranslate;
use plotters::prelude::*;

use crawler_physics::scenario::{Limits, Scenario};
use crawler_physics::wave::Wave;

use crawler_models::operating_point::OperatingPoint;
use crawler_models::optimizer::{linspace, parallel_map};
use crawler_models::prediction::Prediction;

use super::legend::{draw_legend, LegendEntry};
use super::{bounds, models, status_label, tick, Area, FigureOptions, Status};

/// Smallest amplitude of the Fig. 5 sweep in f0, N (log axis up to `limits.f0_max`).
const F0_SWEEP_MIN: f64 = 0.01;

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

/// Draws Fig. 5 into `out/fig5.png` and writes its data (`fig5_<sweep>.csv`, and
/// `fig5_<sweep>_plant.csv` where the plant was run); returns the files, the PNG last.
pub(super) fn fig5(
    scenario: &Scenario,
    out: &Path,
    opts: FigureOptions,
) -> anyhow::Result<Vec<PathBuf>> {
    let base = OperatingPoint {
        wavelengths: 1.0,
        ..OperatingPoint::of(scenario)
    };
    let sweeps = sweeps(&base, &scenario.limits, opts.sweep_points);
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
            let predicted = Predicted::along(&base, sweep);
            files.push(write_models_csv(out, sweep, &predicted)?);
            let plant = plant_points(scenario, sweep, opts.plant_points)?;
            files.extend(write_plant_csv(out, sweep, &plant)?);
            let bands = status_bands(sweep, &predicted.status);
            for (row, metric) in ["V [m/s]", "M [m/J] (log scale)"].iter().enumerate() {
                let curves = model_curves(sweep, &predicted, row);
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

/// The three sweeps of Fig. 5 around `base`'s wave, `points` samples each: omega (rad/s) and k
/// (rad/m) across the limits `lim`, and f0 (N) on a log axis up to `lim.f0_max`.
fn sweeps(base: &OperatingPoint, lim: &Limits, points: usize) -> [Sweep<'static>; 3] {
    let w = base.wave;
    let c = base.body.wave_speed();
    let f0_lo = F0_SWEEP_MIN.min(0.5 * lim.f0_max);
    let log_f0: Vec<f64> = linspace(f0_lo.ln(), lim.f0_max.ln(), points)
        .into_iter()
        .map(f64::exp)
        .collect();
    let scenario_marker = |x: f64| Marker {
        x,
        label: "the scenario's value".into(),
        color: RGBColor(90, 90, 90),
    };
    [
        Sweep {
            name: "omega",
            axis: "omega [rad/s]",
            xs: linspace(lim.omega[0], lim.omega[1], points),
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
            xs: linspace(lim.k[0], lim.k[1], points),
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
    ]
}

/// What the models (in the order of [`models`]) predict at every sample of a sweep.
struct Predicted {
    /// `preds[m][i]`: model `m` at sample `i`.
    preds: Vec<Vec<Prediction>>,
    /// `status[m][i]`: the status of `preds[m][i]`.
    status: Vec<Vec<Status>>,
}

impl Predicted {
    /// Every model at every sample of `sweep`, each on `base` with the sample's wave.
    fn along(base: &OperatingPoint, sweep: &Sweep) -> Self {
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
        Self { preds, status }
    }
}

/// A CSV number: empty where there is none.
fn csv_number(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v:e}"))
}

/// Writes `fig5_<sweep>.csv`: V (m/s), M (m/J) and the status of both models at every sample.
fn write_models_csv(out: &Path, sweep: &Sweep, predicted: &Predicted) -> anyhow::Result<PathBuf> {
    let (preds, status) = (&predicted.preds, &predicted.status);
    let mut csv = format!(
        "{},V_paper,V_improved,M_paper,M_improved,status_paper,status_improved\n",
        sweep.name
    );
    for (i, x) in sweep.xs.iter().enumerate() {
        writeln!(
            csv,
            "{x},{},{},{},{},{},{}",
            csv_number(preds[0][i].velocity),
            csv_number(preds[1][i].velocity),
            csv_number(status[0][i].mileage(&preds[0][i])),
            csv_number(status[1][i].mileage(&preds[1][i])),
            status[0][i].name(),
            status[1][i].name()
        )?;
    }
    let path = out.join(format!("fig5_{}.csv", sweep.name));
    std::fs::write(&path, csv)?;
    Ok(path)
}

/// Writes `fig5_<sweep>_plant.csv` with the plant's V (m/s) and M (m/J), if it was run.
fn write_plant_csv(
    out: &Path,
    sweep: &Sweep,
    plant: &[PlantPoint],
) -> anyhow::Result<Option<PathBuf>> {
    if plant.is_empty() {
        return Ok(None);
    }
    let mut csv = format!("{},V_plant,M_plant\n", sweep.name);
    for (x, v, m) in plant {
        writeln!(csv, "{x},{},{}", csv_number(*v), csv_number(*m))?;
    }
    let path = out.join(format!("fig5_{}_plant.csv", sweep.name));
    std::fs::write(&path, csv)?;
    Ok(Some(path))
}

/// The shaded ranges of a sweep: where each model is undefined, and where it predicts backward
/// motion.
fn status_bands(sweep: &Sweep, status: &[Vec<Status>]) -> Vec<Band> {
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
    bands
}

/// The models' curves of a sweep: V (m/s) in `row` 0, the task's mileage M (m/J) in row 1.
fn model_curves(sweep: &Sweep, predicted: &Predicted, row: usize) -> Vec<Curve> {
    let (preds, status) = (&predicted.preds, &predicted.status);
    models()
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
        .collect()
}

/// `color` mixed with white: `share` of the colour.
fn mix(color: RGBColor, share: f64) -> RGBColor {
    let m = |c: u8| (255.0 - share * (255.0 - f64::from(c))).round() as u8;
    RGBColor(m(color.0), m(color.1), m(color.2))
}

/// The axes of one Fig. 5 panel: the plotted ranges, and the spans the tick labels are rounded
/// against.
struct Frame {
    /// The plotted x range, in the unit of the swept quantity.
    x: (f64, f64),
    /// The plotted y range, m/s (V) or m/J (M).
    y: (f64, f64),
    /// The span the x labels are rounded against (on a log axis: the range's lower end).
    x_span: f64,
    /// The span the y labels are rounded against (on a log axis: the range's lower end).
    y_span: f64,
}

impl Frame {
    /// The frame of a panel showing `curves` and `plant`; `log` is `(log x, log y)`, and on a
    /// log y axis only positive values count.
    fn of(curves: &[Curve], plant: &[(f64, Option<f64>)], log: (bool, bool)) -> Self {
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
        Self {
            x: (x0, x1),
            y: (y0, y1),
            x_span,
            y_span,
        }
    }
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
    let frame = Frame::of(curves, plant, log);
    let ((x0, x1), (y0, y1)) = (frame.x, frame.y);
    let (x_span, y_span) = (frame.x_span, frame.y_span);
    let main = area;
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
            draw_sweep_series(&mut chart, &frame, log.1, curves, bands, markers, plant)?
        }};
    }
    let entries = match log {
        (false, false) => panel!(x0..x1, y0..y1),
        (true, false) => panel!((x0..x1).log_scale(), y0..y1),
        (false, true) => panel!(x0..x1, (y0..y1).log_scale()),
        (true, true) => panel!((x0..x1).log_scale(), (y0..y1).log_scale()),
    };
    Ok(entries)
}

/// Draws the series of a Fig. 5 panel in `frame`, over its mesh: the bands, the zero line, the
/// markers, the curves and the plant's points, in this order; returns their legend entries. On a
/// log y axis (`log_y`) only positive values show.
fn draw_sweep_series<CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'_, BitMapBackend<'_>, CT>,
    frame: &Frame,
    log_y: bool,
    curves: &[Curve],
    bands: &[Band],
    markers: &[Marker],
    plant: &[(f64, Option<f64>)],
) -> anyhow::Result<Vec<LegendEntry>> {
    let ((x0, x1), (y0, y1)) = (frame.x, frame.y);
    let mut entries: Vec<LegendEntry> = Vec::new();
    for b in bands {
        for &(a, z) in &b.ranges {
            chart.draw_series(std::iter::once(Rectangle::new(
                [(a, y0), (z, y1)],
                b.color.filled(),
            )))?;
        }
        entries.push(LegendEntry::patch(&b.label, b.color));
    }
    if !log_y && y0 < 0.0 {
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
            match y.filter(|&y| !log_y || y > 0.0) {
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
        .filter_map(|&(x, y)| y.filter(|&y| !log_y || y > 0.0).map(|y| (x, y)))
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
