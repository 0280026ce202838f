//! The default layout (blueprint) embedded in every recording.
//!
//! Left column: the body crawling in space, the fields u(x) and v(x), the space-time heatmap of u.
//! Right column: the metrics over time with the models' predictions, the tail displacement beside
//! the paper's analytic solution (its Fig. 4), the stick/slip lanes and the event log.

use rerun::blueprint::{
    BarChartView, Blueprint, Grid, Horizontal, Spatial2DView, StateTimelineView, Tabs, TensorView,
    TextLogView, TimeSeriesView, Vertical,
};

use crate::paths;

/// The blueprint of a crawler recording.
pub fn blueprint() -> Blueprint {
    let left = Vertical::new([
        Spatial2DView::new("Body: x + u(x), stick (red) / slip (blue)")
            .with_origin(paths::BODY)
            .into(),
        Tabs::new([
            BarChartView::new("u(x) - mean u [m]")
                .with_origin(paths::FIELD_U)
                .into(),
            BarChartView::new("v(x) [m/s]")
                .with_origin(paths::FIELD_V)
                .into(),
        ])
        .into(),
        TensorView::new("u(x, t) - mean u: space-time heatmap")
            .with_origin(paths::HEATMAP)
            .into(),
    ])
    .with_row_shares([1.0, 1.0, 1.4]);
    let metrics = Grid::new([
        TimeSeriesView::new("Speed V [m/s]")
            .with_origin(paths::metric("velocity"))
            .into(),
        TimeSeriesView::new("Power P [W]")
            .with_origin(paths::metric("power"))
            .into(),
        TimeSeriesView::new("Mileage M [m/J]")
            .with_origin(paths::metric("mileage"))
            .into(),
        TimeSeriesView::new("Max stress [Pa]")
            .with_origin(paths::metric("max_stress"))
            .into(),
        TimeSeriesView::new("Stuck fraction")
            .with_origin(paths::metric("stuck_fraction"))
            .into(),
        TimeSeriesView::new("Tail u(0, t): plant vs paper mu0 + eps mu1 [m]")
            .with_origin(paths::TAIL)
            .into(),
    ])
    .with_grid_columns(2);
    let right = Vertical::new([
        metrics.into(),
        StateTimelineView::new("Stick / slip per node")
            .with_origin(paths::LANES)
            .into(),
        TextLogView::new("Episodes, status, recorder notes")
            .with_origin(paths::LOG)
            .into(),
    ])
    .with_row_shares([2.2, 1.0, 0.8]);
    Blueprint::new(Horizontal::new([left.into(), right.into()]).with_column_shares([1.0, 1.3]))
        .with_auto_views(false)
        .with_auto_layout(false)
}
