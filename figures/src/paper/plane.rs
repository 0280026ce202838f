//! The omega-k heat maps of Fig. 6: cells coloured by speed or by why they have none, the
//! resonance line, a marked point, regions outlined and named, a colour bar and a legend.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crawler_models::optimizer::linspace;

use super::legend::{draw_legend, LegendEntry};
use super::{tick, Area};

/// A cell of an omega-k plane: a speed, or the index of the category that explains its absence.
#[derive(Debug, Clone, Copy)]
pub(super) enum PlaneCell {
    Value(f64),
    Category(usize),
}

/// A category of cells without a speed.
pub(super) struct Category {
    pub(super) label: String,
    pub(super) color: RGBColor,
}

/// One heatmap panel.
pub(super) struct Plane<'a> {
    pub(super) title: String,
    pub(super) omegas: &'a [f64],
    pub(super) ks: &'a [f64],
    pub(super) cells: Vec<PlaneCell>,
    pub(super) categories: Vec<Category>,
    /// A marked point `(omega, k)` and its legend text.
    pub(super) mark: Option<((f64, f64), String)>,
    /// The wave speed, for the resonance line `omega = k c`.
    pub(super) wave_speed: f64,
    /// The colour scale, m/s; speeds below it get its darkest colour (said in the legend).
    pub(super) range: (f64, f64),
    /// Regions outlined in white and labelled: the region of each cell and the regions' names.
    pub(super) regions: Option<(Vec<usize>, Vec<&'static str>)>,
}

/// Draws a heatmap with its colour bar (own range, m/s), the resonance line, the mark and a
/// legend of the categories below.
pub(super) fn draw_plane(area: &Area, plane: &Plane) -> anyhow::Result<()> {
    let (omegas, ks) = (plane.omegas, plane.ks);
    let (w0, w1) = (omegas[0], omegas[omegas.len() - 1]);
    let (k0, k1) = (ks[0], ks[ks.len() - 1]);
    let dw = (w1 - w0) / (omegas.len() - 1).max(1) as f64;
    let dk = (k1 - k0) / (ks.len() - 1).max(1) as f64;
    let ((vmin, vmax), below) = colour_scale(plane);
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
    let mut entries = plane_legend(plane, below, (vmin, vmax), &color_of);
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

/// The colour scale of a panel, m/s: its range, widened where it is flat (`(0, 1)` where it is
/// not finite), and whether some speeds lie below it.
fn colour_scale(plane: &Plane) -> ((f64, f64), bool) {
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
    ((vmin, vmax), below)
}

/// The legend of a panel but its mark: the categories its cells show, the colour of the speeds
/// `below` the scale `(vmin, vmax)` (m/s), the resonance line and the regions' outlines.
fn plane_legend(
    plane: &Plane,
    below: bool,
    (vmin, vmax): (f64, f64),
    color_of: &dyn Fn(f64) -> RGBColor,
) -> Vec<LegendEntry> {
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
    entries
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
    // each row of panels has its own range: say how wide it is, so that a narrow one is not read
    // as a strong dependence
    let span = if vmax.abs() > 0.0 {
        format!(
            "V [m/s], this row's range ({:.1} % of its top)",
            100.0 * (vmax - vmin) / vmax.abs()
        )
    } else {
        "V [m/s], this row's range".to_string()
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
