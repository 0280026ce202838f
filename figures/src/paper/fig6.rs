//! Fig. 6: over the omega-k plane, (a) V at f0 = 1.5 N and (b) the constrained optimal V, the
//! paper's model beside the improved model.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crawler_physics::scenario::{Limits, Scenario};
use crawler_physics::wave::Wave;

use crawler_models::operating_point::OperatingPoint;
use crawler_models::optimizer::{
    linspace, parallel_map, Binding, BodyLength, GridSpec, Infeasibility, ModelChoice,
    OptimizeReport, Problem, DEFAULT_TIE_TOLERANCE,
};
use crawler_models::prediction::Prediction;

use super::plane::{draw_plane, Category, Plane, PlaneCell};
use super::{bounds, models, FigureOptions, Status};

/// The amplitude of the paper's unconstrained Fig. 6(a), N.
const F0_FIG6A: f64 = 1.5;

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

/// Draws Fig. 6 into `out/fig6.png` and writes its data (`fig6a.csv`, `fig6b.csv`); returns the
/// files, the PNG last.
pub(super) fn fig6(
    scenario: &Scenario,
    out: &Path,
    opts: FigureOptions,
) -> anyhow::Result<Vec<PathBuf>> {
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
        let grids: Vec<PlaneGrid> = models()
            .iter()
            .map(|(_, model, _)| {
                let n = if matches!(model, ModelChoice::Paper) {
                    opts.plane_points
                } else {
                    opts.plane_points_improved
                };
                PlaneGrid::new(&lim, n)
            })
            .collect();
        let (mut row_a, mut row_b) = (Vec::new(), Vec::new());
        for ((mname, model, _), grid) in models().iter().zip(&grids) {
            row_a.push(unconstrained_plane(mname, model, &base, grid, &mut csv_a)?);
            let wave_speed = base.body.wave_speed();
            row_b.push(optimal_plane(
                mname, model, &problem, grid, wave_speed, &mut csv_b,
            )?);
        }
        for (row, planes) in [&mut row_a, &mut row_b].into_iter().enumerate() {
            share_colour_range(planes);
            for (col, plane) in planes.iter().enumerate() {
                draw_plane(&panels[2 * row + col], plane)?;
            }
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

/// Gives the panels of one row (the two models) one colour range, m/s: the union of their own
/// ranges, so that a colour means the same speed in both. A panel without a value (a failed
/// optimisation) keeps its own.
fn share_colour_range(planes: &mut [Plane<'_>]) {
    let with_values = |p: &Plane<'_>| {
        p.range.0.is_finite()
            && p.range.1.is_finite()
            && p.cells.iter().any(|c| matches!(c, PlaneCell::Value(_)))
    };
    let shared = planes
        .iter()
        .filter(|p| with_values(p))
        .map(|p| p.range)
        .reduce(|(lo, hi), (l, h)| (lo.min(l), hi.max(h)));
    if let Some(range) = shared {
        for p in planes.iter_mut().filter(|p| with_values(p)) {
            p.range = range;
        }
    }
}

/// The omega-k grid of one model's Fig. 6 panels.
struct PlaneGrid {
    /// Points per axis.
    n: usize,
    /// The angular frequencies, rad/s.
    omegas: Vec<f64>,
    /// The wave numbers, rad/m.
    ks: Vec<f64>,
    /// Every cell's `(omega, k)`, omega running fastest.
    points: Vec<(f64, f64)>,
}

impl PlaneGrid {
    /// `n` by `n` points evenly across the limits `lim`.
    fn new(lim: &Limits, n: usize) -> Self {
        let omegas = linspace(lim.omega[0], lim.omega[1], n);
        let ks = linspace(lim.k[0], lim.k[1], n);
        let points: Vec<(f64, f64)> = ks
            .iter()
            .flat_map(|&k| omegas.iter().map(move |&w| (w, k)))
            .collect();
        Self {
            n,
            omegas,
            ks,
            points,
        }
    }
}

/// The Fig. 6(a) panel of model `mname`: V (m/s) at f0 = [`F0_FIG6A`] on every cell of `grid`,
/// each on `base` with the cell's wave; appends the cells to `csv_a`.
fn unconstrained_plane<'a>(
    mname: &str,
    model: &ModelChoice,
    base: &OperatingPoint,
    grid: &'a PlaneGrid,
    csv_a: &mut String,
) -> anyhow::Result<Plane<'a>> {
    let points = &grid.points;
    let preds: Vec<Prediction> = parallel_map(points, |&(w, k)| {
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
            other => PlaneCell::Category(kinds.iter().position(|&s| s == other).unwrap_or(0)),
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
    Ok(Plane {
        title: format!("(a) V at f0 = {F0_FIG6A} N, {mname} model"),
        omegas: &grid.omegas,
        ks: &grid.ks,
        categories: vec![
            Category {
                label: "V <= 0 predicted (backward)".into(),
                color: infeasibility_color(Infeasibility::NoForwardMotion),
            },
            Category {
                label: if mname == "paper" {
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
                format!("fastest: V = {v:.4} m/s at omega = {w:.1} rad/s, k = {k:.2} rad/m"),
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
    })
}

/// The Fig. 6(b) panel of model `mname`: the constrained optimum of `problem` on every cell of
/// `grid` (the body's wave speed `wave_speed`, m/s, for the resonance line); appends the cells
/// to `csv_b`. If the optimiser fails, a panel saying why.
fn optimal_plane<'a>(
    mname: &str,
    model: &ModelChoice,
    problem: &Problem,
    grid: &'a PlaneGrid,
    wave_speed: f64,
    csv_b: &mut String,
) -> anyhow::Result<Plane<'a>> {
    let n = grid.n;
    let report = problem.optimize(
        model,
        &GridSpec {
            omega_points: n,
            k_points: n,
            refine: true,
            tie_tolerance: DEFAULT_TIE_TOLERANCE,
        },
    );
    Ok(match &report {
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
            constrained_plane(mname, r, &grid.omegas, &grid.ks, wave_speed)
        }
        Err(e) => Plane {
            title: format!("(b) constrained optimal V, {mname} model: {e}"),
            omegas: &grid.omegas,
            ks: &grid.ks,
            cells: vec![PlaneCell::Category(0); grid.points.len()],
            categories: vec![Category {
                label: "infeasible".into(),
                color: infeasibility_color(Infeasibility::Mileage),
            }],
            mark: None,
            wave_speed,
            range: (0.0, 1.0),
            regions: None,
        },
    })
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
}

#[cfg(test)]
mod shared_range_tests {
    use super::*;

    fn plane(range: (f64, f64), cells: Vec<PlaneCell>) -> Plane<'static> {
        Plane {
            title: String::new(),
            omegas: &[1.0, 2.0],
            ks: &[1.0],
            cells,
            categories: Vec::new(),
            mark: None,
            wave_speed: 1.0,
            range,
            regions: None,
        }
    }

    #[test]
    fn the_two_models_panels_of_a_row_share_the_union_of_their_colour_ranges() {
        let v = |x| PlaneCell::Value(x);
        let mut row = vec![
            plane((0.039, 0.0499), vec![v(0.04), v(0.0499)]),
            plane((0.040, 0.0501), vec![v(0.041), v(0.0501)]),
        ];
        share_colour_range(&mut row);
        assert_eq!(row[0].range, (0.039, 0.0501));
        assert_eq!(row[1].range, (0.039, 0.0501));
    }

    #[test]
    fn a_panel_without_values_keeps_its_own_range_and_does_not_widen_the_other() {
        let mut row = vec![
            plane((0.039, 0.0499), vec![PlaneCell::Value(0.045)]),
            plane((0.0, 1.0), Vec::new()),
        ];
        share_colour_range(&mut row);
        assert_eq!(row[0].range, (0.039, 0.0499));
        assert_eq!(row[1].range, (0.0, 1.0));
    }
}
