//! `crawler-controller figures`: the paper's Fig. 5 and Fig. 6, paper model beside the improved model.
//!
//! Fig. 5: V and M against omega, k and f0 (the others at the scenario's values).
//! Fig. 6: (a) unconstrained V over the omega-k plane at f0 = 1.5 N; (b) the constrained optimal V
//! over the omega-k plane (f0 chosen per cell by the optimiser). Each figure is written as PNG and
//! its data as CSV.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crawler_plant::scenario::Scenario;
use crawler_plant::wave::Wave;

use crate::operating_point::OperatingPoint;
use crate::optimizer::{linspace, parallel_map, BodyLength, GridSpec, ModelChoice, Problem};

/// Grid sizes of the figures.
#[derive(Debug, Clone, Copy)]
pub struct FigureOptions {
    /// Points of each Fig. 5 sweep.
    pub sweep_points: usize,
    /// Points per axis of the Fig. 6 planes with the paper's model.
    pub plane_points: usize,
    /// Points per axis of the Fig. 6 planes with the improved model (each cell solves a periodic problem).
    pub plane_points_improved: usize,
}

impl Default for FigureOptions {
    fn default() -> Self {
        Self {
            sweep_points: 120,
            plane_points: 120,
            plane_points_improved: 36,
        }
    }
}

const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
];

/// A Fig. 5 sweep: name, axis label, the values, the wave at each value.
type Sweep<'a> = (
    &'static str,
    &'static str,
    Vec<f64>,
    Box<dyn Fn(f64) -> Wave + Sync + 'a>,
);

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

/// One curve: label, color and points (missing where the model has no answer).
struct Curve {
    label: &'static str,
    color: RGBColor,
    points: Vec<(f64, Option<f64>)>,
}

const PAPER: RGBColor = RGBColor(230, 120, 20);
const IMPROVED: RGBColor = RGBColor(30, 140, 70);

fn draw_lines(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    curves: &[Curve],
) -> anyhow::Result<()> {
    let xs = curves.iter().flat_map(|c| c.points.iter().map(|p| p.0));
    let ys = curves
        .iter()
        .flat_map(|c| c.points.iter().filter_map(|p| p.1));
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let (y0, y1) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
        (a.min(y), b.max(y))
    });
    let (y0, y1) = if y0.is_finite() {
        (y0.min(0.0), y1 + 0.05 * (y1 - y0).abs().max(1e-12))
    } else {
        (0.0, 1.0)
    };
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style(("sans-serif", 13))
        .draw()?;
    for c in curves {
        let color = c.color;
        // a gap where the model is outside its validity
        let mut segment: Vec<(f64, f64)> = Vec::new();
        let mut first = true;
        for &(x, y) in c.points.iter().chain(std::iter::once(&(f64::NAN, None))) {
            match y {
                Some(y) => segment.push((x, y)),
                None if !segment.is_empty() => {
                    let s = chart.draw_series(LineSeries::new(
                        std::mem::take(&mut segment),
                        color.stroke_width(2),
                    ))?;
                    if first {
                        s.label(c.label).legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                        });
                        first = false;
                    }
                }
                None => {}
            }
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()?;
    Ok(())
}

fn draw_heatmap(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    title: &str,
    omegas: &[f64],
    ks: &[f64],
    values: &[Option<f64>],
    vmax: f64,
) -> anyhow::Result<()> {
    let (w0, w1) = (omegas[0], *omegas.last().unwrap());
    let (k0, k1) = (ks[0], *ks.last().unwrap());
    let (dw, dk) = (
        (w1 - w0) / (omegas.len() - 1).max(1) as f64,
        (k1 - k0) / (ks.len() - 1).max(1) as f64,
    );
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(w0 - 0.5 * dw..w1 + 0.5 * dw, k0 - 0.5 * dk..k1 + 0.5 * dk)?;
    chart
        .configure_mesh()
        .x_desc("omega [rad/s]")
        .y_desc("k [rad/m]")
        .label_style(("sans-serif", 13))
        .draw()?;
    let cmap = &plotters::style::colors::colormaps::ViridisRGB;
    chart.draw_series(ks.iter().enumerate().flat_map(|(j, &k)| {
        omegas.iter().enumerate().map(move |(i, &w)| {
            let v = values[j * omegas.len() + i];
            let color = match v {
                Some(v) if vmax > 0.0 => cmap.get_color((v / vmax).clamp(0.0, 1.0)),
                _ => RGBColor(200, 200, 200),
            };
            Rectangle::new(
                [(w - 0.5 * dw, k - 0.5 * dk), (w + 0.5 * dw, k + 0.5 * dk)],
                color.filled(),
            )
        })
    }))?;
    Ok(())
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
    register_font()?;
    std::fs::create_dir_all(out)?;
    let mut files = Vec::new();
    let base = OperatingPoint::of(scenario);
    let lim = scenario.limits;
    // ---- Fig. 5: sweeps; the body is one wavelength of whatever k (paper's convention).
    let at = |w: Wave| OperatingPoint {
        wave: w,
        wavelengths: 1.0,
        ..base
    };
    let sweeps: [Sweep<'_>; 3] = [
        (
            "omega",
            "omega [rad/s]",
            linspace(lim.omega[0], lim.omega[1], opts.sweep_points),
            Box::new(move |x| Wave {
                omega: x,
                ..base.wave
            }),
        ),
        (
            "k",
            "k [rad/m]",
            linspace(lim.k[0], lim.k[1], opts.sweep_points),
            Box::new(move |x| Wave { k: x, ..base.wave }),
        ),
        (
            "f0",
            "f0 [N]",
            linspace(0.02, lim.f0_max, opts.sweep_points),
            Box::new(move |x| Wave { f0: x, ..base.wave }),
        ),
    ];
    let png = out.join("fig5.png");
    let root = BitMapBackend::new(&png, (1800, 1000)).into_drawing_area();
    root.fill(&WHITE)?;
    let cells = root.split_evenly((2, 3));
    for (col, (name, label, xs, wave_of)) in sweeps.iter().enumerate() {
        let preds: Vec<Vec<_>> = models()
            .iter()
            .map(|(_, m, _)| parallel_map(xs, |&x| m.predict(&at(wave_of(x)))))
            .collect();
        let mut csv = format!("{name},V_paper,V_improved,M_paper,M_improved\n");
        for (i, x) in xs.iter().enumerate() {
            let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
            writeln!(
                csv,
                "{x},{},{},{},{}",
                f(preds[0][i].velocity),
                f(preds[1][i].velocity),
                f(preds[0][i].mileage),
                f(preds[1][i].mileage)
            )?;
        }
        let path = out.join(format!("fig5_{name}.csv"));
        std::fs::write(&path, csv)?;
        files.push(path);
        for (row, (metric, unit)) in [("V", "m/s"), ("M", "m/J")].iter().enumerate() {
            let curves: Vec<Curve> = models()
                .iter()
                .zip(&preds)
                .map(|((mname, _, color), p)| Curve {
                    label: mname,
                    color: *color,
                    points: xs
                        .iter()
                        .zip(p)
                        .map(|(&x, q)| (x, if row == 0 { q.velocity } else { q.mileage }))
                        .collect(),
                })
                .collect();
            let others = match *name {
                "omega" => format!("k = {:.2} rad/m, f0 = {} N", base.wave.k, base.wave.f0),
                "k" => format!(
                    "omega = {:.1} rad/s, f0 = {} N",
                    base.wave.omega, base.wave.f0
                ),
                _ => format!(
                    "omega = {:.1} rad/s, k = {:.2} rad/m",
                    base.wave.omega, base.wave.k
                ),
            };
            draw_lines(
                &cells[row * 3 + col],
                &format!("{metric} vs {name} ({others})"),
                label,
                &format!("{metric} [{unit}]"),
                &curves,
            )?;
        }
    }
    root.present()?;
    drop(cells);
    drop(root);
    files.push(png);
    // ---- Fig. 6: the omega-k plane.
    let problem = Problem {
        body: base.body,
        friction: base.friction,
        task: scenario.task,
        limits: lim,
        body_length: BodyLength::OneWavelength,
    };
    let png = out.join("fig6.png");
    let root = BitMapBackend::new(&png, (1600, 1300)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((2, 2));
    let mut csv_a = String::from("omega,k,model,V_unconstrained_f0_1.5N\n");
    let mut csv_b = String::from("omega,k,model,f0,V,binding\n");
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
        let unconstrained: Vec<Option<f64>> = parallel_map(&points, |&(w, k)| {
            model
                .predict(&at(Wave {
                    f0: 1.5,
                    k,
                    omega: w,
                    phase: 0.0,
                }))
                .velocity
        });
        for ((w, k), v) in points.iter().zip(&unconstrained) {
            writeln!(
                csv_a,
                "{w},{k},{mname},{}",
                v.map_or(String::new(), |v| format!("{v:e}"))
            )?;
        }
        let vmax = unconstrained
            .iter()
            .flatten()
            .fold(0.0f64, |a, &b| a.max(b));
        draw_heatmap(
            &panels[col],
            &format!("(a) V at f0 = 1.5 N, {mname} model (max {vmax:.4} m/s)"),
            &omegas,
            &ks,
            &unconstrained,
            vmax,
        )?;
        let report = problem.optimize(
            model,
            &GridSpec {
                omega_points: n,
                k_points: n,
                refine: false,
            },
        );
        let values: Vec<Option<f64>> = match &report {
            Ok(r) => {
                for cell in &r.cells {
                    writeln!(
                        csv_b,
                        "{},{},{mname},{},{},{:?}",
                        cell.omega,
                        cell.k,
                        cell.f0.map_or(String::new(), |v| format!("{v:e}")),
                        cell.velocity.map_or(String::new(), |v| format!("{v:e}")),
                        cell.binding
                    )?;
                }
                r.cells.iter().map(|c| c.velocity).collect()
            }
            Err(_) => vec![None; points.len()],
        };
        let vmax = values.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
        draw_heatmap(
            &panels[2 + col],
            &format!("(b) constrained optimal V, {mname} (max {vmax:.4} m/s)"),
            &omegas,
            &ks,
            &values,
            vmax,
        )?;
    }
    root.present()?;
    drop(panels);
    drop(root);
    for (name, csv) in [("fig6a.csv", csv_a), ("fig6b.csv", csv_b)] {
        let path = out.join(name);
        std::fs::write(&path, csv)?;
        files.push(path);
    }
    files.push(png);
    Ok(files)
}
