//! Recordings read back with the rerun crate's own reader.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use zenoh::Wait;

use crawler_e2e::{json, read_recording, repo_root, simulate, Recording, Run};
use crawler_protocol::{decode, Actuation, RunKeys, State, WaveMsg};

/// For each of `paths`, the steps at which the recording at `rrd` has a row of it, read with
/// Rerun's dataframe API (a query on the step timeline, one entity at a time, rows where its
/// first component is set).
fn dataframe_steps(rrd: &std::path::Path, paths: &[&str]) -> BTreeMap<String, Vec<i64>> {
    use rerun::dataframe::external::arrow::array::{Array, Int64Array};
    use rerun::dataframe::external::re_chunk_store::ColumnDescriptor;
    use rerun::dataframe::{
        ChunkStoreConfig, EntityPathFilter, QueryEngine, QueryExpression, TimelineName,
    };
    let engines = QueryEngine::from_rrd_filepath(&ChunkStoreConfig::DEFAULT, rrd)
        .unwrap_or_else(|e| panic!("the dataframe API cannot open {}: {e:#}", rrd.display()));
    let (_, engine) = engines
        .iter()
        .find(|(id, _)| id.is_recording())
        .expect("a recording store");
    let mut out = BTreeMap::new();
    for &path in paths {
        let filter = EntityPathFilter::parse_strict(format!("/{path}")).unwrap();
        let contents = engine
            .iter_entity_paths_sorted(&filter)
            .map(|p| (p, None))
            .collect();
        let mut query = QueryExpression {
            filtered_index: Some(TimelineName::from("step")),
            view_contents: Some(contents),
            ..Default::default()
        };
        let schema = engine.selected_schema_for_query(&query);
        let first = schema.iter().find_map(|c| match c {
            ColumnDescriptor::Component(c) if !c.is_static => Some(c.clone()),
            _ => None,
        });
        let Some(first) = first else {
            out.insert(path.to_string(), Vec::new());
            continue;
        };
        query.filtered_is_not_null = Some(first.into());
        let mut steps = Vec::new();
        for batch in engine.query(query).into_batch_iter() {
            let column = batch
                .column_by_name("step")
                .expect("a step column")
                .as_any()
                .downcast_ref::<Int64Array>()
                .expect("steps are integers")
                .clone();
            steps.extend((0..column.len()).map(|i| column.value(i)));
        }
        out.insert(path.to_string(), steps);
    }
    out
}

/// Rows of the boxes at `path` in the recording at `rrd`, in step order: the step, the boxes'
/// centres and their half sizes.
type BoxRows = Vec<(i64, Vec<[f32; 2]>, Vec<[f32; 2]>)>;
fn boxes(rrd: &std::path::Path, path: &str) -> BoxRows {
    use rerun::dataframe::external::re_chunk_store::{ChunkStore, ChunkStoreConfig};
    let file = std::fs::File::open(rrd).unwrap();
    let stores = ChunkStore::from_rrd_reader(
        &ChunkStoreConfig::ALL_DISABLED,
        &mut std::io::BufReader::new(file),
    )
    .unwrap();
    let centres = rerun::Boxes2D::descriptor_centers().component;
    let halves = rerun::Boxes2D::descriptor_half_sizes().component;
    let mut out = BoxRows::new();
    for (id, store) in &stores {
        if !id.is_recording() {
            continue;
        }
        for chunk in store.iter_physical_chunks() {
            if chunk.entity_path().to_string() != format!("/{path}") {
                continue;
            }
            let Some(steps) = chunk.timelines().get(&rerun::TimelineName::from("step")) else {
                continue;
            };
            let c = chunk.iter_component::<rerun::components::Position2D>(centres);
            let h = chunk.iter_component::<rerun::components::HalfSize2D>(halves);
            for (i, (c, h)) in c.zip(h).enumerate() {
                out.push((
                    steps.times_raw()[i],
                    c.iter().map(|p| [p.x(), p.y()]).collect(),
                    h.iter().map(|p| [p.0.x(), p.0.y()]).collect(),
                ));
            }
        }
    }
    out.sort_by_key(|r| r.0);
    out
}

const PLANT: &[&str] = &["--eps", "1", "--t-end", "8", "--json"];
const WAVE: &[&str] = &["--policy", "wave", "--f0", "0.2", "--alpha", "0.5"];

/// Every actuation the run's controller sends, by step (a passive subscriber of the run: it knows
/// the zenoh password, not the message key).
fn spy_actuation(run: &Run) -> (zenoh::Session, Arc<Mutex<BTreeMap<u64, Actuation>>>) {
    let session = run.transport_only_session(128);
    let keys = RunKeys::new(&run.id).unwrap();
    let sent = Arc::new(Mutex::new(BTreeMap::new()));
    let s2 = sent.clone();
    session
        .declare_subscriber(keys.actuation())
        .callback(move |s| {
            if let Ok(a) = decode::<Actuation>(&s.payload().to_bytes()) {
                s2.lock().unwrap().insert(a.step, a);
            }
        })
        .background()
        .wait()
        .unwrap();
    std::thread::sleep(Duration::from_millis(200));
    (session, sent)
}

/// The recording's applied wave equals, at every state n >= 1, the wave the controller sent for
/// step n - 1; returns how many states were checked.
fn applied_wave_is_what_was_sent(rec: &Recording, sent: &BTreeMap<u64, Actuation>) -> usize {
    type Param = fn(&WaveMsg) -> f64;
    let params: [(&str, Param); 4] = [
        ("f0", |w| w.f0),
        ("k", |w| w.k),
        ("omega", |w| w.omega),
        ("phase", |w| w.phase),
    ];
    let rows = rec.entity("actuation/applied/f0").rows;
    for (name, get) in params {
        let e = rec.entity(&format!("actuation/applied/{name}"));
        assert_eq!(e.rows, rows, "{name}");
        assert_eq!(e.scalars.len(), rows, "{name}");
        for (&step, &value) in e.steps.iter().zip(&e.scalars) {
            let a = sent
                .get(&(step as u64 - 1))
                .unwrap_or_else(|| panic!("no actuation seen for step {}", step - 1));
            let wave = a.wave.expect("a wave was sent");
            assert_eq!(
                value.to_bits(),
                get(&wave).to_bits(),
                "applied {name} at state {step}: recorded {value}, sent {}",
                get(&wave)
            );
        }
    }
    rows
}

#[test]
fn a_full_recording_holds_the_metrics_of_the_in_process_run() {
    let run = Run::new("rec");
    let rrd = run.path("run.rrd");
    let plant = run.plant(PLANT);
    let bridge = run.bridge(&rrd, &["--every", "2"]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let (_spy, sent) = spy_actuation(&run);
    let controller = run.controller(WAVE);
    let p = plant.wait(Duration::from_secs(60));
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    let b = bridge.wait(Duration::from_secs(60));
    assert!(
        p.status.success() && b.status.success(),
        "{}\n{}",
        p.stderr,
        b.stderr
    );
    let summary = json(&p.stdout);
    let sim = simulate(&[
        "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", "8",
    ]);

    // the run ends at the first communication point at or after t_end (H is a whole
    // number of internal steps), as the in-process run says
    let last = sim["macro_steps"].as_u64().unwrap();
    assert!((8000..8200).contains(&last), "{last} communication steps");
    assert_eq!(summary["macro_steps"], sim["macro_steps"]);

    let rec = read_recording(&rrd).unwrap();
    // every state: the tail displacement is logged for each step 0..=last
    let tail = rec.entity("tail/plant");
    assert_eq!(tail.rows as u64, last + 1);
    assert_eq!(tail.steps.first(), Some(&0));
    assert_eq!(tail.steps.last(), Some(&(last as i64)));
    assert!(
        tail.steps.windows(2).all(|w| w[1] == w[0] + 1),
        "states out of order or missing"
    );
    // the fields of every 2nd state, and the last, read with the dataframe API: nothing thinned
    let every_2nd: Vec<i64> = (0..=last as i64)
        .filter(|n| n % 2 == 0 || *n == last as i64)
        .collect();
    let fields = [
        "fields/u",
        "fields/v",
        "fields/tension",
        "body/segments",
        "body/world",
    ];
    for (path, steps) in dataframe_steps(&rrd, &fields) {
        assert_eq!(steps, every_2nd, "{path}");
    }
    assert_eq!(rec.entity("fields/u").rows, every_2nd.len());
    assert!(
        b.stderr.contains(&format!(
            "{} states ({} with fields): the fields of every 2nd state recorded",
            last + 1,
            every_2nd.len()
        )),
        "{}",
        b.stderr
    );
    assert!(rec.entity("heatmap/u").rows >= 1);
    // per-period metrics with the models' predictions overlaid, and the running (clock) blocks
    let blocks = rec.entity("metrics/velocity/plant").rows;
    assert!(blocks >= 40, "{blocks} metric blocks; bridge: {}", b.stderr);
    assert!(rec.entity("metrics/velocity/improved").rows >= blocks);
    assert_eq!(
        rec.entity("metrics/power/paper").rows,
        rec.entity("metrics/velocity/improved").rows
    );
    // a clock block every numerics.block = 2 pi / 74.3 s (the scenario's period) from t = 0
    let running = rec.entity("metrics/velocity/running").rows;
    assert_eq!(running, 94, "clock blocks of 84.6 ms in 8 s");
    // stick-slip: lanes and episode log
    assert!(
        rec.entities
            .keys()
            .filter(|k| k.starts_with("lanes/node_"))
            .count()
            >= 32
    );
    every_episode_is_recorded(&rec, &b.stderr);
    // the plant's final metrics, equal to the in-process run of the same scenario
    for key in [
        "velocity",
        "power",
        "mileage",
        "max_stress",
        "max_strain",
        "stuck_fraction",
    ] {
        let recorded = rec.entity(&format!("summary/{key}")).scalars[0];
        assert_eq!(
            recorded,
            sim[key].as_f64().unwrap(),
            "{key}: recording vs in-process"
        );
        assert_eq!(
            recorded,
            summary[key].as_f64().unwrap(),
            "{key}: recording vs plant"
        );
    }
    // and the recorded tail equals the in-process trajectory's last state (bit for bit)
    assert_eq!(summary["state_digest"], sim["state_digest"]);
    // what the plant applied: at every state after the first, the wave the controller sent for
    // the step before, and no field
    let sent = sent.lock().unwrap();
    assert_eq!(
        sent.len() as u64,
        last,
        "the spy saw every answer, steps 0 to {}",
        last - 1
    );
    let checked = applied_wave_is_what_was_sent(&rec, &sent);
    assert_eq!(checked as u64, last, "states 1 to {last}");
    assert_eq!(rec.entity("actuation/applied/f0").steps.first(), Some(&1));
    assert!(!rec.entities.contains_key("actuation/applied/field"));
}

/// Every stick episode, a row apiece, as many as the recorder's closing line counts.
fn every_episode_is_recorded(rec: &Recording, stderr: &str) {
    let episodes = rec.entity("events/episodes");
    assert_eq!(episodes.rows, episodes.nodes, "one episode a row");
    assert!(episodes.rows > 1000, "{} episodes", episodes.rows);
    assert!(
        stderr.contains(&format!("{} stick episodes (whole run)", episodes.nodes)),
        "{} episodes recorded; recorder: {stderr}",
        episodes.nodes
    );
}

/// A controller that drives the body with a field (the `reflex` policy: a new field every step):
/// the recording holds, at every state whose fields it recorded (every 8th here), the field the
/// controller sent for the step before, value for value.
#[test]
fn a_recording_holds_the_field_the_plant_applied() {
    let run = Run::new("recfield");
    let rrd = run.path("field.rrd");
    let plant = run.plant(&["--eps", "1", "--cells", "128", "--t-end", "5.2", "--json"]);
    let bridge = run.bridge(&rrd, &["--every", "8"]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let (_spy, sent) = spy_actuation(&run);
    let controller = run.controller(&["--policy", "reflex"]);
    let p = plant.wait(Duration::from_secs(120));
    let c = controller.wait(Duration::from_secs(30));
    let b = bridge.wait(Duration::from_secs(60));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    let last = json(&p.stdout)["macro_steps"].as_u64().unwrap();
    let sent = sent.lock().unwrap();
    assert_eq!(sent.len() as u64, last, "the spy saw every answer");
    let rec = read_recording(&rrd).unwrap();
    let field = &rec.entity("actuation/applied/field").bars;
    // the states whose fields were recorded, but the first (nothing applied before it): every
    // 8th and the last
    let u = rec.entity("fields/u");
    let every_8th: Vec<i64> = (0..=last as i64)
        .filter(|n| n % 8 == 0 || *n == last as i64)
        .collect();
    assert_eq!(u.steps, every_8th);
    assert_eq!(
        field.iter().map(|b| b.0).collect::<Vec<_>>(),
        u.steps[1..],
        "the applied field is recorded with the other fields"
    );
    let mut changed = 0;
    for (step, values) in field {
        assert!(
            (*step as u64).is_multiple_of(8) || *step as u64 == last,
            "a field at step {step}"
        );
        let a = &sent[&(*step as u64 - 1)];
        let f = a.field.as_ref().expect("the reflex policy sends fields");
        assert_eq!(values.len(), 128);
        assert!(
            values
                .iter()
                .zip(f)
                .all(|(r, s)| r.to_bits() == s.to_bits()),
            "state {step}: the recorded field is not the one sent for step {}",
            step - 1
        );
        changed += usize::from(sent.get(&(*step as u64)).and_then(|n| n.field.as_ref()) != Some(f));
    }
    assert!(changed > 0, "the reflex policy's field never changed");
    // a field run records no wave parameters
    assert!(!rec.entities.contains_key("actuation/applied/f0"));
}

/// Tracks the latest step the plant published (a passive subscriber of the run).
fn watch_steps(run: &Run) -> (zenoh::Session, Arc<AtomicU64>) {
    let session = run.transport_only_session(128);
    let keys = RunKeys::new(&run.id).unwrap();
    let latest = Arc::new(AtomicU64::new(0));
    let l2 = latest.clone();
    session
        .declare_subscriber(keys.state())
        .callback(move |s| {
            if let Ok(st) = decode::<State>(&s.payload().to_bytes()) {
                l2.fetch_max(st.step, Ordering::Relaxed);
            }
        })
        .background()
        .wait()
        .unwrap();
    (session, latest)
}

fn interrupted_recording(signal: &str) {
    let run = Run::new("sig");
    let rrd = run.path("sig.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "40"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let (_watch, latest) = watch_steps(&run);
    let controller = run.controller(WAVE);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    let t0 = Instant::now();
    while latest.load(Ordering::Relaxed) < 3000 && t0.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(20));
    }
    // steps per second of the run, to translate "one second" into steps
    let (s0, w0) = (latest.load(Ordering::Relaxed), Instant::now());
    std::thread::sleep(Duration::from_millis(500));
    let rate = (latest.load(Ordering::Relaxed) - s0) as f64 / w0.elapsed().as_secs_f64();
    let at_kill = latest.load(Ordering::Relaxed);
    bridge.signal(signal);
    let b = bridge.wait(Duration::from_secs(20));
    if signal != "-9" {
        // closed properly, and says it was interrupted: 130, like every program of the project
        assert_eq!(b.status.code(), Some(130), "{}", b.stderr);
        assert!(
            b.stderr.contains("interrupted; recording closed properly"),
            "{}",
            b.stderr
        );
    }
    // the co-simulation goes on without the recorder and finishes
    let p = plant.wait(Duration::from_secs(120));
    assert!(
        p.status.success(),
        "the plant must not notice the recorder going away: {}",
        p.stderr
    );
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    // the file is readable, in order, and lost at most about one second of data
    let rec = read_recording(&rrd)
        .unwrap_or_else(|e| panic!("recording unreadable after {signal}: {e:#}"));
    let tail = rec.entity("tail/plant");
    let last = *tail.steps.last().unwrap() as u64;
    assert!(tail.steps.windows(2).all(|w| w[1] > w[0]));
    let lost = at_kill.saturating_sub(last) as f64 / rate;
    eprintln!("{signal}: {lost:.3} s lost at {rate:.0} steps/s");
    assert!(
        lost <= 1.0,
        "{signal}: last recorded step {last}, {at_kill} at the kill: {lost:.2} s lost"
    );
}

#[test]
fn sigint_finishes_the_recording_properly() {
    interrupted_recording("-INT");
}

#[test]
fn sigterm_finishes_the_recording_properly() {
    interrupted_recording("-TERM");
}

#[test]
fn kill_9_leaves_a_readable_recording_and_the_run_goes_on() {
    interrupted_recording("-9");
}

/// The pipe of `scenarios/patchy-pipe.toml` as a step line: eps 0.1, and 0.8 on the ten
/// patches [0.5 + 0.5 j, 0.75 + 0.5 j), written from the scenario file's numbers, not from any
/// code of the project.
fn patchy_pipe_eps(x: f64) -> f64 {
    let on_patch = (0..10).any(|j| {
        let from = 0.5 + 0.5 * j as f64;
        (from..from + 0.25).contains(&x)
    });
    if on_patch {
        0.8
    } else {
        0.1
    }
}

/// Plant (`scenario` on `cells` cells, to t = 6 s, just past the 5 s of settling), recorder and
/// a resonant wave controller (f0 = 1 N); the recording and its path, once all three ended well.
fn record_wave_run(
    run: &Run,
    scenario: &std::path::Path,
    cells: usize,
) -> (Recording, std::path::PathBuf) {
    let rrd = run.path("run.rrd");
    let scenario = scenario.to_str().unwrap();
    let cells = cells.to_string();
    let plant = run.plant(&["--scenario", scenario, "--cells", &cells, "--t-end", "6"]);
    let bridge = run.bridge(&rrd, &[]);
    // the recorder knows the model and the pipe before the first state (no state comes before
    // a controller joins)
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(&["--policy", "wave", "--f0", "1.0", "--alpha", "1.0"]);
    let p = plant.wait(Duration::from_secs(120));
    assert!(p.status.success(), "{}", p.stderr);
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    let b = bridge.wait(Duration::from_secs(60));
    assert!(b.status.success(), "{}", b.stderr);
    (read_recording(&rrd).unwrap(), rrd)
}

#[test]
fn the_recording_draws_the_pipe_the_plant_resolved_even_when_controllers_are_not_told() {
    let run = Run::new("pipe");
    let scenario = repo_root().join("scenarios/patchy-pipe.toml");
    // a short run on a coarse grid, the body's centre starting at X = 0.5 m, a patch's edge
    let (rec, _) = record_wave_run(&run, &scenario, 64);

    // the map: a step line equal to the scenario's patches, though the plant told controllers
    // only eps = 0.1 (disclose = false)
    let strips = &rec.entity("pipe/eps").strips;
    assert_eq!(strips.len(), 1, "one static row");
    let line = &strips[0][0];
    let xs: Vec<f64> = line.iter().map(|p| p[0] as f64).collect();
    assert!(xs.windows(2).all(|w| w[1] >= w[0]), "X never decreases");
    assert!(xs[0] <= -0.9 && *xs.last().unwrap() >= 5.25, "{xs:?}");
    // every horizontal run of the line lies at the scenario's eps over its whole span
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a[0] < b[0] {
            assert_eq!(a[1], b[1], "a horizontal run between {a:?} and {b:?}");
            for t in [0.01, 0.5, 0.99] {
                let x = a[0] as f64 + t * (b[0] - a[0]) as f64;
                // drawn at y = -eps: up is more friction in the viewer
                assert_eq!(-a[1], patchy_pipe_eps(x) as f32, "eps at X = {x}");
            }
        }
    }
    // the edges are exactly the patches' edges
    let edges: Vec<f32> = line
        .windows(2)
        .filter(|w| w[0][0] == w[1][0])
        .map(|w| w[0][0])
        .collect();
    let expected: Vec<f32> = (0..10)
        .flat_map(|j| [0.5 + 0.5 * j as f32, 0.75 + 0.5 * j as f32])
        .collect();
    assert_eq!(edges, expected);
    let n_f = &rec.entity("pipe/n_f").strips[0][0];
    assert!(n_f.iter().all(|p| p[1] == -0.5), "n_F is uniform: {n_f:?}");

    // the friction under the centre: one value per state, always one the pipe has; the cells
    // tile the body [0, 1 m) at rest (node 0's cell half at the tail, half at the head), so the
    // centre of mass starts at X = 0.5 m exactly, the first patch's edge, on the patch (patches
    // are [from, to)); half a cell back it would be on the plain pipe
    let centre = rec.entity("pipe/centre_eps");
    assert_eq!(centre.steps, rec.entity("tail/plant").steps);
    assert!(centre.scalars.iter().all(|&e| e == 0.1 || e == 0.8));
    assert_eq!(centre.steps[0], 0);
    assert_eq!(centre.scalars[0], 0.8, "the centre at t = 0");
    // the nodes on the line at every step whose fields were recorded, node 0 at X = u(0, t)
    let body = &rec.entity("pipe/body").points;
    let steps: Vec<i64> = body.iter().map(|p| p.0).collect();
    assert_eq!(steps, rec.entity("fields/u").steps);
    assert_nodes_drawn_at(&rec, "pipe/body", 0.0);
}

/// Node 0 of every row of the points at `entity` is at `offset + u(0, t)` (m), `u(0, t)` the
/// plant's tail displacement the recording holds at the same step.
fn assert_nodes_drawn_at(rec: &Recording, entity: &str, offset: f64) {
    let tail = rec.entity("tail/plant");
    let rows = &rec.entity(entity).points;
    assert!(!rows.is_empty(), "{entity} has no points");
    for (step, points) in rows {
        let k = tail
            .steps
            .binary_search(step)
            .expect("a tail value at every state");
        let expected = (offset + tail.scalars[k]) as f32;
        assert_eq!(points[0][0], expected, "{entity}: node 0 at step {step}");
    }
}

/// A free body's nodes are the cell centres: the recording draws node 0 half a cell from the
/// tail's end, in the body view and on the pipe, and looks the pipe's friction up there.
#[test]
fn a_free_body_is_drawn_where_its_nodes_are() {
    let run = Run::new("freepipe");
    // the free-body scenario (2.5 m, two free ends) in a pipe with one patch under its middle
    let body = std::fs::read_to_string(repo_root().join("scenarios/free-body.toml")).unwrap();
    let scenario = run.path("free-pipe.toml");
    let pipe = "\n[pipe]\nstart = 0.0\n\n[[pipe.features]]\nkind = \"patch\"\nfrom = 1.0\nto = 1.5\neps = 0.8\n";
    std::fs::write(&scenario, body + pipe).unwrap();
    // 80 cells: dx = 31.25 mm, node 0 at 15.625 mm
    let (rec, rrd) = record_wave_run(&run, &scenario, 80);

    let half_cell = 0.5 * 2.5 / 80.0;
    assert_nodes_drawn_at(&rec, "pipe/body", half_cell);
    // in the body view (the body's frame, in body lengths, its centre of mass at 0) the tail
    // cell's centre is node 0, at (dx / 2 + u(0, t) - mean u - L / 2) / L; the body starts at
    // rest, so mean u is the task's distance
    let cells = boxes(&rrd, "body/segments");
    assert_eq!(
        cells.iter().map(|c| c.0).collect::<Vec<_>>(),
        rec.entity("fields/u").steps
    );
    let (tail, distance) = (rec.entity("tail/plant"), rec.entity("task/distance"));
    assert_eq!(tail.steps, distance.steps);
    for (step, centres, halves) in &cells {
        assert_eq!((centres.len(), halves.len()), (80, 80));
        let k = tail
            .steps
            .binary_search(step)
            .expect("a tail value at every state");
        let node0 = (half_cell + tail.scalars[k] - distance.scalars[k] - 1.25) / 2.5;
        assert!(
            (f64::from(centres[0][0]) - node0).abs() < 1e-6,
            "step {step}: tail cell at {}, node 0 at {node0}",
            centres[0][0]
        );
        // the cells tile the body: each ends where the next begins
        for i in 0..79 {
            let end = centres[i][0] + halves[i][0];
            let begin = centres[i + 1][0] - halves[i + 1][0];
            assert!(
                (end - begin).abs() < 1e-6,
                "step {step}: cells {i} and {}",
                i + 1
            );
        }
    }
    // every node on the pipe's line: eps 0.8 on [1, 1.5), 0.1 elsewhere, at its own X
    for (step, points) in &rec.entity("pipe/body").points {
        assert_eq!(points.len(), 80);
        for p in points {
            let eps = if (1.0..1.5).contains(&f64::from(p[0])) {
                0.8
            } else {
                0.1
            };
            assert_eq!(-p[1], eps as f32, "node at X = {} at step {step}", p[0]);
        }
    }
    // the friction under the centre of mass, which starts at 1.25 m, on the patch, and crawls
    // off its end (1.5 m)
    let centre = rec.entity("pipe/centre_eps");
    assert_eq!(centre.steps, rec.entity("tail/plant").steps);
    assert!(centre.scalars.iter().all(|&e| e == 0.1 || e == 0.8));
    assert_eq!((centre.steps[0], centre.scalars[0]), (0, 0.8));
    assert!(
        centre.scalars.contains(&0.1),
        "the centre never left the patch"
    );
}

/// A plant that dies (kill -9) sends neither its last state nor its final status: the recorder
/// notices its liveliness token go, closes the recording properly within seconds and says why.
#[test]
fn a_recorder_whose_plant_dies_closes_the_recording() {
    let run = Run::new("plantdies");
    let rrd = run.path("dies.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "600"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let _controller = run.controller(WAVE);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(500));
    plant.signal("-9");
    let killed = Instant::now();
    let b = bridge.wait(Duration::from_secs(30));
    assert!(
        killed.elapsed() < Duration::from_secs(15),
        "the recorder took {:?} to notice",
        killed.elapsed()
    );
    assert!(b.status.success(), "{}", b.stderr);
    assert!(b.stderr.contains("recording closed"), "{}", b.stderr);
    let rec = read_recording(&rrd).unwrap();
    assert!(rec.entity("tail/plant").rows > 100);
}

/// A controller of a user's own that changes its wave every step (the Python example, its
/// amplitude changed at every answer) restarts the plant's forcing-period blocks at every step,
/// so it closes none of them; its metric panels are full all the same: the plant's clock blocks
/// (one every `numerics.block` seconds of the run, whatever the actuation does) give the running
/// V, P, M, stress and stuck fraction, and every state its own values.
#[test]
fn a_controller_that_changes_its_wave_every_step_has_full_metric_panels() {
    let run = Run::new("everystep");
    let rrd = run.path("every.rrd");
    // a Python controller of the package's client, its wave's amplitude changed at every step
    let wrapper = run.path("changing_controller.py");
    std::fs::write(
        &wrapper,
        r#"import argparse, math
import softcrawler
from softcrawler.client import add_arguments, from_arguments

class Changing:
    name = "changing"
    def __init__(self, f0, alpha):
        self.f0, self.alpha, self.n = f0, alpha, 0
    def reset(self, context):
        body = context["body"]
        c = math.sqrt(body["area"] * body["youngs_modulus"] / body["density"])
        self.k = 2.0 * math.pi / context["length"]
        self.omega = self.alpha * (self.k * c)
    def act(self, observation):
        self.n += 1
        f0 = self.f0 * (1.0 + 0.2 * (self.n % 5) / 5.0)
        return softcrawler.Wave(f0=f0, k=self.k, omega=self.omega)

ap = argparse.ArgumentParser()
add_arguments(ap)
ap.add_argument("--f0", type=float)
ap.add_argument("--alpha", type=float)
args = ap.parse_args()
from_arguments(args).run(Changing(args.f0, args.alpha))
"#,
    )
    .unwrap();
    let plant = run.plant(&["--eps", "1", "--t-end", "6", "--json"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let (_spy, sent) = spy_actuation(&run);
    let controller = run.python_example(
        wrapper.to_str().unwrap(),
        &["--f0", "0.2", "--alpha", "0.5"],
    );
    let p = plant.wait(Duration::from_secs(120));
    let c = controller.wait(Duration::from_secs(60));
    let b = bridge.wait(Duration::from_secs(60));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    let report = json(&p.stdout);
    let last = report["macro_steps"].as_u64().unwrap();
    // clock blocks of the scenario's forcing period 2 pi / (k c), c = sqrt(A_c E / rho), from
    // t = 0: block j - 1 closes at the first internal step starting at or after j periods, and
    // the run's last internal step starts at t_end - dt
    let (t_end, dt) = (
        report["t_end"].as_f64().unwrap(),
        report["dt"].as_f64().unwrap(),
    );
    let omega = std::f64::consts::TAU * (1e-4f64 * 140e3 / 0.1).sqrt();
    let period = std::f64::consts::TAU / omega;
    let clock_blocks = (1..)
        .take_while(|&j| f64::from(j) * period <= t_end - dt)
        .count();
    // the amplitude did change at every step
    let sent = sent.lock().unwrap();
    let f0: Vec<f64> = sent.values().filter_map(|a| a.wave.map(|w| w.f0)).collect();
    assert!(f0.windows(2).all(|w| w[0] != w[1]), "a wave that stays");
    let rec = read_recording(&rrd).unwrap();
    // no forcing-period block ever closes
    assert_eq!(rec.entity("metrics/velocity/plant").rows, 0);
    // a clock block every 2 pi / 74.3 s (the scenario's period) of the 6 s run: about 70
    assert!((69..=72).contains(&clock_blocks), "{clock_blocks}");
    for metric in [
        "velocity",
        "power",
        "mileage",
        "max_stress",
        "stuck_fraction",
    ] {
        let running = rec.entity(&format!("metrics/{metric}/running"));
        assert_eq!(running.rows, clock_blocks, "{metric}: clock blocks");
        assert!(running.scalars.iter().all(|v| v.is_finite()));
        // and every state its own values (a mileage only where the step's power is positive)
        let per_step = rec.entity(&format!("step/{metric}")).rows as u64;
        if metric == "mileage" {
            assert!(per_step > last / 2, "{metric}: {per_step} states");
        } else {
            assert_eq!(per_step, last + 1, "{metric}: every state");
        }
    }
    let speed = &rec.entity("metrics/velocity/running").scalars;
    assert!(speed.iter().any(|&v| v > 0.0), "the body crawls: {speed:?}");
}
