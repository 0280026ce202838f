//! Columnar logging: what a block of states adds to each entity, kept as columns and sent as one
//! chunk per entity (Rerun's `send_columns`), on the step and simulated-time timelines.
//!
//! A row-by-row log call per entity per state costs the SDK a time context, an Arrow conversion and
//! a batcher hand-off each; a chunk per entity per block of states costs them once per block.
//! Every chunk goes to the file; a live viewer gets the same chunk of every thin entity (scalars,
//! lanes, logs) and only the last row of a thick one (fields, the body, the heatmap): a decimated
//! stream that costs the file nothing ([`Sinks`]).

use std::collections::BTreeMap;

use rerun::log::{Chunk, ChunkId, TimeColumn};
use rerun::{RecordingStream, SerializedComponentColumn};

use crate::paths;

/// The step and time of each row of a column.
#[derive(Debug, Default, Clone)]
pub struct Rows {
    steps: Vec<i64>,
    times: Vec<f64>,
}

impl Rows {
    fn push(&mut self, step: u64, time: f64) {
        self.steps.push(step as i64);
        self.times.push(time);
    }

    /// Rows held.
    pub fn len(&self) -> usize {
        self.steps.len()
    }

    /// True if no row is held.
    pub fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// The two time columns of the rows held, which are handed over (the rows are cleared).
    fn take(&mut self) -> [TimeColumn; 2] {
        [
            TimeColumn::new_sequence(paths::STEP_TIMELINE, std::mem::take(&mut self.steps)),
            TimeColumn::new_duration_secs(paths::TIME_TIMELINE, std::mem::take(&mut self.times)),
        ]
    }
}

/// What the live viewer gets of a chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Live {
    /// The whole chunk.
    All,
    /// Its last row (a thick entity: a field, the body, the heatmap).
    Last,
}

/// The recording's streams: the file's and, with a live viewer, the viewer's (the same recording,
/// its own stream, so the viewer's pace never reaches the file).
pub struct Sinks {
    /// The stream to the file.
    pub file: RecordingStream,
    /// The stream to the live viewer.
    pub view: Option<RecordingStream>,
}

impl Sinks {
    /// Both streams.
    pub fn each(&self) -> impl Iterator<Item = &RecordingStream> {
        std::iter::once(&self.file).chain(self.view.as_ref())
    }

    /// Sends the rows `index` of `columns` at `path` as one chunk to the file, and to the viewer
    /// as `live` says.
    pub fn send(
        &self,
        path: &str,
        index: [TimeColumn; 2],
        columns: impl IntoIterator<Item = SerializedComponentColumn>,
        live: Live,
    ) -> anyhow::Result<()> {
        let chunk = Chunk::from_auto_row_ids(
            ChunkId::new(),
            path.into(),
            index
                .into_iter()
                .map(|c| (*c.timeline().name(), c))
                .collect(),
            columns.into_iter().collect(),
        )?;
        if let Some(view) = &self.view {
            let rows = chunk.num_rows();
            match live {
                Live::All => view.send_chunk(chunk.clone()),
                Live::Last if rows > 0 => view.send_chunk(chunk.row_sliced_deep(rows - 1, 1)),
                Live::Last => {}
            }
        }
        self.file.send_chunk(chunk);
        Ok(())
    }

    /// Logs static data to both streams.
    pub fn log_static(
        &self,
        path: impl Into<String>,
        what: &dyn rerun::AsComponents,
    ) -> anyhow::Result<()> {
        let path = path.into();
        for rec in self.each() {
            rec.log_static(path.as_str(), what)?;
        }
        Ok(())
    }

    /// Logs one row at `step`, `time` to both streams.
    pub fn log_at(
        &self,
        (step, time): (u64, f64),
        path: impl Into<String>,
        what: &dyn rerun::AsComponents,
    ) -> anyhow::Result<()> {
        let path = path.into();
        for rec in self.each() {
            rec.set_time_sequence(paths::STEP_TIMELINE, step as i64);
            rec.set_duration_secs(paths::TIME_TIMELINE, time);
            rec.log(path.as_str(), what)?;
        }
        Ok(())
    }
}

/// A scalar series.
#[derive(Debug, Default)]
struct Scalar {
    rows: Rows,
    values: Vec<f64>,
}

/// A field: one bar chart of `width` values per row.
#[derive(Debug, Default)]
struct Field<T> {
    rows: Rows,
    values: Vec<T>,
    width: usize,
}

/// Boxes: `width` boxes per row.
#[derive(Debug, Default)]
struct Boxes {
    rows: Rows,
    centers: Vec<[f32; 2]>,
    half_sizes: Vec<[f32; 2]>,
    classes: Vec<u16>,
    width: usize,
}

/// Points: `width` points per row, each with a class.
#[derive(Debug, Default)]
struct Points {
    rows: Rows,
    positions: Vec<[f32; 2]>,
    classes: Vec<u16>,
    width: usize,
}

/// A lane: a state's value where it changes.
#[derive(Debug, Default)]
struct Lane {
    rows: Rows,
    values: Vec<String>,
}

/// A translation per row.
#[derive(Debug, Default)]
struct Translations {
    rows: Rows,
    values: Vec<[f32; 3]>,
}

/// The columns of the current block, by entity path.
#[derive(Debug, Default)]
pub struct Columns {
    scalars: BTreeMap<String, Scalar>,
    fields: BTreeMap<&'static str, Field<f32>>,
    fields64: BTreeMap<&'static str, Field<f64>>,
    boxes: BTreeMap<&'static str, Boxes>,
    points: BTreeMap<&'static str, Points>,
    lanes: BTreeMap<String, Lane>,
    translations: BTreeMap<&'static str, Translations>,
}

impl Columns {
    /// Adds `value` to the scalar series `path`.
    pub fn scalar(&mut self, path: &str, at: (u64, f64), value: f64) {
        let s = match self.scalars.get_mut(path) {
            Some(s) => s,
            None => self.scalars.entry(path.to_string()).or_default(),
        };
        s.rows.push(at.0, at.1);
        s.values.push(value);
    }

    /// Adds a row of `values` to the f32 field `path`.
    pub fn field(&mut self, path: &'static str, at: (u64, f64), values: impl Iterator<Item = f32>) {
        let f = self.fields.entry(path).or_default();
        let before = f.values.len();
        f.values.extend(values);
        f.width = f.values.len() - before;
        f.rows.push(at.0, at.1);
    }

    /// Adds a row of `values` to the f64 field `path`.
    pub fn field64(&mut self, path: &'static str, at: (u64, f64), values: &[f64]) {
        let f = self.fields64.entry(path).or_default();
        f.values.extend_from_slice(values);
        f.width = values.len();
        f.rows.push(at.0, at.1);
    }

    /// Adds a row of boxes (`centers`, `half_sizes`, `classes`, as many of each) to `path`.
    pub fn boxes(
        &mut self,
        path: &'static str,
        at: (u64, f64),
        boxes: impl Iterator<Item = ([f32; 2], [f32; 2], u16)>,
    ) {
        let b = self.boxes.entry(path).or_default();
        let before = b.classes.len();
        for (c, h, k) in boxes {
            b.centers.push(c);
            b.half_sizes.push(h);
            b.classes.push(k);
        }
        b.width = b.classes.len() - before;
        b.rows.push(at.0, at.1);
    }

    /// Adds a row of points (`position`, `class`) to `path`.
    pub fn points(
        &mut self,
        path: &'static str,
        at: (u64, f64),
        points: impl Iterator<Item = ([f32; 2], u16)>,
    ) {
        let p = self.points.entry(path).or_default();
        let before = p.classes.len();
        for (x, k) in points {
            p.positions.push(x);
            p.classes.push(k);
        }
        p.width = p.classes.len() - before;
        p.rows.push(at.0, at.1);
    }

    /// Adds a change of the lane `path` to `value`.
    pub fn lane(&mut self, path: &str, at: (u64, f64), value: &str) {
        let l = match self.lanes.get_mut(path) {
            Some(l) => l,
            None => self.lanes.entry(path.to_string()).or_default(),
        };
        l.rows.push(at.0, at.1);
        l.values.push(value.to_string());
    }

    /// Adds a translation of `path`.
    pub fn translation(&mut self, path: &'static str, at: (u64, f64), value: [f32; 3]) {
        let t = self.translations.entry(path).or_default();
        t.rows.push(at.0, at.1);
        t.values.push(value);
    }

    /// Rows of the scalar series `path` held (for tests).
    pub fn scalar_rows(&self, path: &str) -> usize {
        self.scalars.get(path).map_or(0, |s| s.rows.len())
    }

    /// Sends every column held as one chunk per entity, and empties them.
    pub fn send(&mut self, sinks: &Sinks) -> anyhow::Result<()> {
        self.send_thick(sinks)?;
        self.send_thin(sinks)
    }

    /// Sends the thin columns (scalars and lanes: a few bytes a row) as one chunk per entity.
    pub fn send_thin(&mut self, sinks: &Sinks) -> anyhow::Result<()> {
        for (path, s) in &mut self.scalars {
            if s.rows.is_empty() {
                continue;
            }
            let values = std::mem::take(&mut s.values);
            let columns = rerun::Scalars::new(values).columns_of_unit_batches()?;
            sinks.send(path, s.rows.take(), columns, Live::All)?;
        }
        for (path, l) in &mut self.lanes {
            if l.rows.is_empty() {
                continue;
            }
            let columns = rerun::StateChange::update_fields()
                .with_state(std::mem::take(&mut l.values))
                .columns_of_unit_batches()?;
            sinks.send(path, l.rows.take(), columns, Live::All)?;
        }
        Ok(())
    }

    /// Sends the thick columns (fields, boxes, points, translations: a row per recorded state, a
    /// few bytes a cell) as one chunk per entity.
    pub fn send_thick(&mut self, sinks: &Sinks) -> anyhow::Result<()> {
        for (path, f) in &mut self.fields {
            if f.rows.is_empty() {
                continue;
            }
            let values = std::mem::take(&mut f.values);
            let tensors = values.chunks(f.width.max(1)).map(|row| {
                rerun::datatypes::TensorData::new(
                    vec![row.len() as u64],
                    rerun::datatypes::TensorBuffer::F32(row.to_vec().into()),
                )
            });
            let columns = rerun::BarChart::update_fields()
                .with_many_values(tensors)
                .columns_of_unit_batches()?;
            sinks.send(path, f.rows.take(), columns, Live::Last)?;
        }
        for (path, f) in &mut self.fields64 {
            if f.rows.is_empty() {
                continue;
            }
            let values = std::mem::take(&mut f.values);
            let tensors = values.chunks(f.width.max(1)).map(|row| {
                rerun::datatypes::TensorData::new(
                    vec![row.len() as u64],
                    rerun::datatypes::TensorBuffer::F64(row.to_vec().into()),
                )
            });
            let columns = rerun::BarChart::update_fields()
                .with_many_values(tensors)
                .columns_of_unit_batches()?;
            sinks.send(path, f.rows.take(), columns, Live::Last)?;
        }
        for (path, b) in &mut self.boxes {
            if b.rows.is_empty() {
                continue;
            }
            let rows = b.rows.len();
            let columns = rerun::Boxes2D::update_fields()
                .with_centers(std::mem::take(&mut b.centers))
                .with_half_sizes(std::mem::take(&mut b.half_sizes))
                .with_class_ids(std::mem::take(&mut b.classes))
                .columns(std::iter::repeat_n(b.width, rows))?;
            sinks.send(path, b.rows.take(), columns, Live::Last)?;
        }
        for (path, p) in &mut self.points {
            if p.rows.is_empty() {
                continue;
            }
            let rows = p.rows.len();
            let columns = rerun::Points2D::update_fields()
                .with_positions(std::mem::take(&mut p.positions))
                .with_class_ids(std::mem::take(&mut p.classes))
                .columns(std::iter::repeat_n(p.width, rows))?;
            sinks.send(path, p.rows.take(), columns, Live::Last)?;
        }
        for (path, t) in &mut self.translations {
            if t.rows.is_empty() {
                continue;
            }
            let columns = rerun::Transform3D::update_fields()
                .with_many_translation(std::mem::take(&mut t.values))
                .columns_of_unit_batches()?;
            sinks.send(path, t.rows.take(), columns, Live::Last)?;
        }
        Ok(())
    }
}
