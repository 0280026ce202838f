//! The default layout (blueprint) embedded in every recording.
//!
//! Left column: the body in its own frame (the camera follows it) with the pipe under it; tabs
//! with the space-time heatmap of u (shown first), the pipe's map, the fields u, v and T, and the
//! actuation the plant applied; the lanes of the acting controller and of stick and slip.
//! Right column: tabs with the metrics over time (the plant's per-period and running blocks
//! against both models' predictions, the tail beside the paper's Fig. 4, the task's distance and
//! energy against their targets; shown first) and the per-step values; tabs with the text log
//! (statuses, the recorder's notes) and the stick episodes as a table.
//! The time panel shows simulated time, in seconds.
//!
//! The blueprint entities are written directly (containers, views, viewport, panels), the same
//! entities the SDK's blueprint builder writes, because the layout also sets a property that
//! builder does not expose in 0.36: the time axis of every plot spans the whole run.

use std::collections::hash_map::RandomState;
use std::hash::{BuildHasher, Hasher};

use rerun::blueprint::components::{
    ActiveTab, AutoLayout, AutoViews, ColumnShare, ContainerKind, Corner2D, GridColumns,
    IncludedContent, PanelState, PlayState, QueryExpression, RootContainer, RowShare, TimelineName,
    ViewClass, ViewFit, VisualBounds2D as VisualBounds2DComponent,
};
use rerun::components::Colormap;
use rerun::external::re_log_types::{BlueprintActivationCommand, LogMsg};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    ContainerBlueprint, PanelBlueprint, PlotLegend, TensorScalarMapping, TensorViewFit, TimeAxis,
    TimePanelBlueprint, ViewBlueprint, ViewContents, ViewportBlueprint, VisualBounds2D,
};
use rerun::external::re_sdk_types::blueprint::components::TimeRange;
use rerun::external::re_sdk_types::datatypes::{
    Range1D, Range2D, TimeRange as TimeRangeData, TimeRangeBoundary,
};
use rerun::RecordingStream;

use crate::paths;

/// A property of a view (a blueprint archetype logged under the view's path).
#[derive(Debug, Clone, Copy)]
enum Prop {
    /// A time series spanning the whole run, its legend in the bottom-right corner (the curves
    /// start on the left).
    WholeRun,
    /// A 2D view showing `[x0, x1] x [y0, y1]`.
    Bounds([f64; 4]),
    /// A tensor filling the view, in a diverging colour map.
    Heatmap,
}

/// A node of the layout tree.
enum Node {
    Container {
        kind: ContainerKind,
        children: Vec<Node>,
        col_shares: Vec<f32>,
        row_shares: Vec<f32>,
        grid_columns: Option<u32>,
        name: Option<&'static str>,
    },
    View {
        class: &'static str,
        name: String,
        origin: String,
        props: Vec<Prop>,
    },
}

fn view(class: &'static str, name: &str, origin: impl Into<String>) -> Node {
    let props = if class == "TimeSeries" {
        vec![Prop::WholeRun]
    } else {
        Vec::new()
    };
    Node::View {
        class,
        name: name.to_string(),
        origin: origin.into(),
        props,
    }
}

fn with(mut node: Node, prop: Prop) -> Node {
    if let Node::View { props, .. } = &mut node {
        props.push(prop);
    }
    node
}

fn container(kind: ContainerKind, children: Vec<Node>) -> Node {
    Node::Container {
        kind,
        children,
        col_shares: Vec::new(),
        row_shares: Vec::new(),
        grid_columns: None,
        name: None,
    }
}

fn named(mut node: Node, title: &'static str) -> Node {
    if let Node::Container { name, .. } = &mut node {
        *name = Some(title);
    }
    node
}

fn shares(mut node: Node, cols: &[f32], rows: &[f32]) -> Node {
    if let Node::Container {
        col_shares,
        row_shares,
        ..
    } = &mut node
    {
        *col_shares = cols.to_vec();
        *row_shares = rows.to_vec();
    }
    node
}

fn grid(children: Vec<Node>, columns: u32) -> Node {
    let mut g = container(ContainerKind::Grid, children);
    if let Node::Container { grid_columns, .. } = &mut g {
        *grid_columns = Some(columns);
    }
    g
}

/// The body, the heatmap and the lanes (left column).
fn left() -> Node {
    let body = with(
        view(
            "2D",
            "Body (in body lengths; the camera follows it): cell thickness follows the strain (x4), red stick, blue slip; the pipe under it (band: eps), ruler in m",
            paths::BODY,
        ),
        Prop::Bounds([-0.62, 0.62, -0.11, 0.11]),
    );
    let tabs = container(
        ContainerKind::Tabs,
        vec![
            with(
                view(
                    "Tensor",
                    "u(x, t) - mean u: space-time heatmap (time down, in s; x tail to head)",
                    paths::HEATMAP,
                ),
                Prop::Heatmap,
            ),
            view(
                "2D",
                "Pipe: eps(X) orange, n_F(X) green, the body's nodes on eps(X) (stick red, slip blue); X [m]",
                paths::PIPE,
            ),
            view(
                "TimeSeries",
                "eps of the pipe under the centre of mass",
                paths::PIPE_CENTRE_EPS,
            ),
            view("BarChart", "u(x) - mean u [m]", paths::FIELD_U),
            view("BarChart", "v(x) [m/s]", paths::FIELD_V),
            view("BarChart", "Tension T(x) [N]", paths::FIELD_TENSION),
            view(
                "BarChart",
                "Applied muscle force A_m f(x) [N] (field actuation)",
                paths::APPLIED_FIELD,
            ),
            view(
                "TimeSeries",
                "Applied wave: f0 [N], k [rad/m], omega [rad/s], phase [rad]",
                paths::APPLIED,
            ),
        ],
    );
    shares(
        container(
            ContainerKind::Vertical,
            vec![
                body,
                tabs,
                view(
                    "StateTimeline",
                    "Acting controller; stick / slip per node",
                    paths::LANES,
                ),
            ],
        ),
        &[],
        &[1.0, 1.5, 1.0],
    )
}

/// The metrics against both models, the tail, the task, the per-step values and the log (right
/// column).
fn right() -> Node {
    let metric = |name: &str, title: &str| {
        view(
            "TimeSeries",
            &format!("{title}: plant per period (white), running (blue), paper (orange), improved (green)"),
            paths::metric(name),
        )
    };
    let metrics = grid(
        vec![
            metric("velocity", "Speed V [m/s]"),
            metric("power", "Power P [W]"),
            metric("mileage", "Mileage M [m/J]"),
            metric("max_stress", "Max stress [Pa]"),
            metric("stuck_fraction", "Stuck fraction"),
            view(
                "TimeSeries",
                "Tail u(0, t) [m]: plant vs paper mu0 + eps mu1",
                paths::TAIL,
            ),
            view(
                "TimeSeries",
                "Task: distance travelled [m] against D",
                paths::task("distance"),
            ),
            view(
                "TimeSeries",
                "Task: energy spent [J] against J0",
                paths::task("energy"),
            ),
        ],
        2,
    );
    let per_step = grid(
        paths::METRICS
            .iter()
            .map(|m| {
                view(
                    "TimeSeries",
                    &format!("{} of each step", m.name()),
                    paths::step_series(m.name()),
                )
            })
            .collect(),
        2,
    );
    let tabs = container(
        ContainerKind::Tabs,
        vec![
            named(metrics, "Metrics and task"),
            named(per_step, "Per step"),
        ],
    );
    shares(
        container(
            ContainerKind::Vertical,
            vec![
                tabs,
                container(
                    ContainerKind::Tabs,
                    vec![
                        view("TextLog", "Status and recorder notes", paths::LOG),
                        view("Dataframe", "Stick episodes", paths::EPISODES),
                    ],
                ),
            ],
        ),
        &[],
        &[3.0, 0.7],
    )
}

/// The layout tree.
fn tree() -> Node {
    shares(
        container(ContainerKind::Horizontal, vec![left(), right()]),
        &[1.1, 1.0],
        &[],
    )
}

/// A random version-4 UUID.
pub(crate) fn uuid() -> [u8; 16] {
    let mut b = [0u8; 16];
    for chunk in b.chunks_mut(8) {
        let mut h = RandomState::new().build_hasher();
        h.write_u128(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos()),
        );
        chunk.copy_from_slice(&h.finish().to_le_bytes());
    }
    b[6] = (b[6] & 0x0f) | 0x40;
    b[8] = (b[8] & 0x3f) | 0x80;
    b
}

pub(crate) fn uuid_string(b: &[u8; 16]) -> String {
    let h: String = b.iter().map(|x| format!("{x:02x}")).collect();
    format!(
        "{}-{}-{}-{}-{}",
        &h[0..8],
        &h[8..12],
        &h[12..16],
        &h[16..20],
        &h[20..32]
    )
}

/// Logs the property `prop` of the view at `path`.
fn log_prop(path: &str, prop: Prop, bp: &RecordingStream) -> anyhow::Result<()> {
    match prop {
        Prop::WholeRun => {
            // Show the whole run, not a window around the time cursor.
            let everything = TimeRange(TimeRangeData {
                start: TimeRangeBoundary::Infinite,
                end: TimeRangeBoundary::Infinite,
            });
            bp.log(
                format!("{path}/TimeAxis"),
                &TimeAxis::new().with_view_range(everything),
            )?;
            bp.log(
                format!("{path}/PlotLegend"),
                &PlotLegend::new().with_corner(Corner2D::RightBottom),
            )?;
        }
        Prop::Bounds([x0, x1, y0, y1]) => {
            let range = Range2D {
                x_range: Range1D([x0, x1]),
                y_range: Range1D([y0, y1]),
            };
            bp.log(
                format!("{path}/VisualBounds2D"),
                &VisualBounds2D::new(VisualBounds2DComponent(range)),
            )?;
        }
        Prop::Heatmap => {
            bp.log(
                format!("{path}/TensorScalarMapping"),
                &TensorScalarMapping::new().with_colormap(Colormap::CyanToYellow),
            )?;
            bp.log(
                format!("{path}/TensorViewFit"),
                &TensorViewFit::new().with_scaling(ViewFit::Fill),
            )?;
        }
    }
    Ok(())
}

/// Logs `node` and its children; returns its blueprint path and id.
fn log_node(node: &Node, bp: &RecordingStream) -> anyhow::Result<(String, [u8; 16])> {
    let id = uuid();
    match node {
        Node::View {
            class,
            name,
            origin,
            props,
        } => {
            let path = format!("view/{}", uuid_string(&id));
            bp.log(
                format!("{path}/ViewContents"),
                &ViewContents::new([QueryExpression("$origin/**".into())]),
            )?;
            bp.log(
                path.as_str(),
                &ViewBlueprint::new(ViewClass((*class).into()))
                    .with_display_name(name.as_str())
                    .with_space_origin(origin.as_str()),
            )?;
            for &prop in props {
                log_prop(&path, prop, bp)?;
            }
            Ok((path, id))
        }
        Node::Container {
            kind,
            children,
            col_shares,
            row_shares,
            grid_columns,
            name,
        } => {
            let mut contents = Vec::new();
            for child in children {
                contents.push(IncludedContent(log_node(child, bp)?.0.into()));
            }
            let first = contents.first().cloned();
            let mut arch = ContainerBlueprint::new(*kind).with_contents(contents);
            if let (ContainerKind::Tabs, Some(first)) = (kind, first) {
                arch = arch.with_active_tab(ActiveTab(first.0));
            }
            if !col_shares.is_empty() {
                arch = arch.with_col_shares(col_shares.iter().map(|&s| ColumnShare(s.into())));
            }
            if !row_shares.is_empty() {
                arch = arch.with_row_shares(row_shares.iter().map(|&s| RowShare(s.into())));
            }
            if let Some(g) = grid_columns {
                arch = arch.with_grid_columns(GridColumns((*g).into()));
            }
            if let Some(n) = name {
                arch = arch.with_display_name(*n);
            }
            let path = format!("container/{}", uuid_string(&id));
            bp.log(path.as_str(), &arch)?;
            Ok((path, id))
        }
    }
}

/// The blueprint as messages of a blueprint store of application `app`.
pub fn messages(app: &'static str) -> anyhow::Result<Vec<LogMsg>> {
    let (bp, storage) = rerun::RecordingStreamBuilder::new(app)
        .recording_id(uuid_string(&uuid()))
        .blueprint()
        .memory()?;
    bp.set_time_sequence("blueprint", 0);
    let (_, root) = log_node(&tree(), &bp)?;
    bp.log(
        "viewport",
        &ViewportBlueprint::new()
            .with_root_container(RootContainer(
                rerun::external::re_sdk_types::datatypes::Uuid { bytes: root },
            ))
            .with_auto_layout(AutoLayout(false.into()))
            .with_auto_views(AutoViews(false.into())),
    )?;
    bp.log(
        "blueprint_panel",
        &PanelBlueprint::new().with_state(PanelState::Collapsed),
    )?;
    bp.log(
        "selection_panel",
        &PanelBlueprint::new().with_state(PanelState::Collapsed),
    )?;
    bp.log(
        "time_panel",
        &TimePanelBlueprint::new()
            .with_state(PanelState::Collapsed)
            .with_timeline(TimelineName(paths::TIME_TIMELINE.into()))
            .with_play_state(PlayState::Following),
    )?;
    bp.flush_blocking()?;
    Ok(storage.take())
}

/// Sends the layout into `rec` and makes it the active and default one.
pub fn send(rec: &RecordingStream) -> anyhow::Result<()> {
    let msgs = messages("crawler")?;
    let Some(first) = msgs.first() else {
        anyhow::bail!("empty blueprint")
    };
    let blueprint_id = first.store_id().clone();
    rec.send_blueprint(
        msgs,
        BlueprintActivationCommand {
            blueprint_id,
            make_active: true,
            make_default: true,
        },
    );
    Ok(())
}
