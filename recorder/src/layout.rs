//! The default layout (blueprint) embedded in every recording.
//!
//! Left column: the body crawling in space, the fields u(x) and v(x) and the actuation the plant
//! applied (a field, or a wave's parameters over time), the space-time heatmap of u.
//! Right column: the metrics over time with the models' predictions, the tail displacement beside
//! the paper's analytic solution (its Fig. 4), the stick/slip lanes and the event log.
//!
//! The blueprint entities are written directly (containers, views, viewport, panels), the same
//! entities the SDK's blueprint builder writes, because the layout also sets a property that
//! builder does not expose in 0.36: the time axis of every plot spans the whole run.

use std::collections::hash_map::RandomState;
use std::hash::{BuildHasher, Hasher};

use rerun::blueprint::components::{
    AutoLayout, AutoViews, ColumnShare, ContainerKind, GridColumns, IncludedContent, PanelState,
    PlayState, QueryExpression, RootContainer, RowShare, TimelineName, ViewClass,
};
use rerun::external::re_log_types::{BlueprintActivationCommand, LogMsg};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    ContainerBlueprint, PanelBlueprint, TimeAxis, TimePanelBlueprint, ViewBlueprint, ViewContents,
    ViewportBlueprint,
};
use rerun::external::re_sdk_types::blueprint::components::TimeRange;
use rerun::external::re_sdk_types::datatypes::{TimeRange as TimeRangeData, TimeRangeBoundary};
use rerun::RecordingStream;

use crate::paths;

/// A node of the layout tree.
enum Node {
    Container {
        kind: ContainerKind,
        children: Vec<Node>,
        col_shares: Vec<f32>,
        row_shares: Vec<f32>,
        grid_columns: Option<u32>,
    },
    View {
        class: &'static str,
        name: String,
        origin: String,
    },
}

fn view(class: &'static str, name: &str, origin: impl Into<String>) -> Node {
    Node::View {
        class,
        name: name.to_string(),
        origin: origin.into(),
    }
}

fn container(kind: ContainerKind, children: Vec<Node>) -> Node {
    Node::Container {
        kind,
        children,
        col_shares: Vec::new(),
        row_shares: Vec::new(),
        grid_columns: None,
    }
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

/// The layout tree.
fn tree() -> Node {
    let left = shares(
        container(
            ContainerKind::Vertical,
            vec![
                view(
                    "2D",
                    "Body: x + u (top), deformation magnified (bottom); stick red, slip blue",
                    paths::BODY,
                ),
                container(
                    ContainerKind::Tabs,
                    vec![
                        view("BarChart", "u(x) - mean u [m]", paths::FIELD_U),
                        view("BarChart", "v(x) [m/s]", paths::FIELD_V),
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
                ),
                container(
                    ContainerKind::Tabs,
                    vec![
                        view(
                            "Tensor",
                            "u(x, t) - mean u: space-time heatmap",
                            paths::HEATMAP,
                        ),
                        view(
                            "2D",
                            "Pipe: eps(X) orange, n_F(X) green, nodes on eps(X) (stick red, slip blue); X [m]",
                            paths::PIPE,
                        ),
                    ],
                ),
            ],
        ),
        &[],
        &[1.0, 1.0, 1.4],
    );
    let mut metrics = container(
        ContainerKind::Grid,
        vec![
            view("TimeSeries", "Speed V [m/s]", paths::metric("velocity")),
            view("TimeSeries", "Power P [W]", paths::metric("power")),
            view("TimeSeries", "Mileage M [m/J]", paths::metric("mileage")),
            view("TimeSeries", "Max stress [Pa]", paths::metric("max_stress")),
            view(
                "TimeSeries",
                "Stuck fraction",
                paths::metric("stuck_fraction"),
            ),
            view(
                "TimeSeries",
                "Tail u(0, t): plant vs paper mu0 + eps mu1 [m]",
                paths::TAIL,
            ),
            view(
                "TimeSeries",
                "eps of the pipe under the centre of mass (where the friction varies)",
                paths::PIPE_CENTRE_EPS,
            ),
        ],
    );
    if let Node::Container { grid_columns, .. } = &mut metrics {
        *grid_columns = Some(2);
    }
    let right = shares(
        container(
            ContainerKind::Vertical,
            vec![
                metrics,
                view("StateTimeline", "Stick / slip per node", paths::LANES),
                view("TextLog", "Episodes, status, recorder notes", paths::LOG),
            ],
        ),
        &[],
        &[2.2, 1.0, 0.8],
    );
    shares(
        container(ContainerKind::Horizontal, vec![left, right]),
        &[1.0, 1.3],
        &[],
    )
}

/// A random version-4 UUID.
fn uuid() -> [u8; 16] {
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

fn uuid_string(b: &[u8; 16]) -> String {
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

/// Logs `node` and its children; returns its blueprint path and id.
fn log_node(node: &Node, bp: &RecordingStream) -> anyhow::Result<(String, [u8; 16])> {
    let id = uuid();
    match node {
        Node::View {
            class,
            name,
            origin,
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
            if *class == "TimeSeries" {
                // Show the whole run, not a window around the time cursor.
                let everything = TimeRange(TimeRangeData {
                    start: TimeRangeBoundary::Infinite,
                    end: TimeRangeBoundary::Infinite,
                });
                bp.log(
                    format!("{path}/TimeAxis"),
                    &TimeAxis::new().with_view_range(everything),
                )?;
            }
            Ok((path, id))
        }
        Node::Container {
            kind,
            children,
            col_shares,
            row_shares,
            grid_columns,
        } => {
            let mut contents = Vec::new();
            for child in children {
                contents.push(IncludedContent(log_node(child, bp)?.0.into()));
            }
            let mut arch = ContainerBlueprint::new(*kind).with_contents(contents);
            if !col_shares.is_empty() {
                arch = arch.with_col_shares(col_shares.iter().map(|&s| ColumnShare(s.into())));
            }
            if !row_shares.is_empty() {
                arch = arch.with_row_shares(row_shares.iter().map(|&s| RowShare(s.into())));
            }
            if let Some(g) = grid_columns {
                arch = arch.with_grid_columns(GridColumns((*g).into()));
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
            .with_timeline(TimelineName("step".into()))
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
