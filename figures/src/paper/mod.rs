//! `crawler-controller figures`: the paper's Fig. 5 and Fig. 6, paper model beside the improved model.
//!
//! Fig. 5: V and M against omega, k and f0, the others at the scenario's values, on the paper's
//! one-wavelength body. Where a model predicts backward motion its mileage is not drawn (the task's
//! mileage is distance forward per joule), and the ranges where a model is undefined or predicts
//! backward motion are shaded and named in the legend.
//!
//! Fig. 6: over the omega-k plane, (a) V at f0 = 1.5 N (the paper's unconstrained Fig. 6(a)) and
//! (b) the constrained optimal V with f0 chosen per cell by the optimiser (Fig. 6(b)), each row's
//! two panels (the two models) with one colour range over that row's speeds (so that a colour
//! means the same speed in both models, and the dependence of (b) on k alone shows as horizontal
//! bands), the resonance line `omega = k c`, the fastest or optimal point marked, and every cell
//! without a value coloured by its cause, named in the legend.
//!
//! Each figure is written as PNG and its data as CSV.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use crawler_physics::scenario::Scenario;

use crawler_models::optimizer::ModelChoice;
use crawler_models::prediction::Prediction;

mod fig5;
mod fig6;
mod legend;
mod plane;

use fig5::fig5;
use fig6::fig6;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crawler_models::operating_point::OperatingPoint;
    use crawler_physics::wave::Wave;

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
