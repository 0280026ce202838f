//! The space-time heatmap of `u - mean u`: blocks of rows (recorded states, time running down)
//! by nodes (tail to head), one tensor per block at the block's first state, its dimensions
//! named with the block's time span in seconds.

use rerun::log::TimeColumn;
use rerun::SerializedComponentColumn;

use crate::paths;

/// The block being filled.
#[derive(Debug)]
pub struct Heat {
    rows_max: usize,
    rows: usize,
    width: usize,
    data: Vec<f32>,
    first: (u64, f64),
    last_time: f64,
}

impl Heat {
    /// Blocks of `rows_max` rows.
    pub fn new(rows_max: usize) -> Self {
        Self {
            rows_max: rows_max.max(1),
            rows: 0,
            width: 0,
            data: Vec::new(),
            first: (0, 0.0),
            last_time: 0.0,
        }
    }

    /// Adds the row of the state at `at`.
    pub fn push(&mut self, at: (u64, f64), row: impl Iterator<Item = f32>) {
        if self.rows == 0 {
            self.first = at;
            self.data.clear();
        }
        let before = self.data.len();
        self.data.extend(row);
        self.width = self.data.len() - before;
        self.rows += 1;
        self.last_time = at.1;
    }

    /// True when the block holds its rows.
    pub fn full(&self) -> bool {
        self.rows >= self.rows_max
    }

    /// The block as a one-row chunk's time columns and components, if it holds rows; empties it.
    pub fn take(
        &mut self,
    ) -> anyhow::Result<Option<([TimeColumn; 2], Vec<SerializedComponentColumn>)>> {
        if self.rows == 0 {
            return Ok(None);
        }
        let rows = std::mem::take(&mut self.rows);
        let data = rerun::TensorData::new(
            vec![rows as u64, self.width as u64],
            rerun::datatypes::TensorBuffer::F32(std::mem::take(&mut self.data).into()),
        );
        let names = [
            format!(
                "t from {:.4} s to {:.4} s ({rows} states, down)",
                self.first.1, self.last_time
            ),
            format!("x: {} nodes, tail to head", self.width),
        ];
        let columns = rerun::Tensor::new(data)
            .with_dim_names(names)
            .columns_of_unit_batches()?
            .collect();
        let (step, time) = self.first;
        Ok(Some((
            [
                TimeColumn::new_sequence(paths::STEP_TIMELINE, [step as i64]),
                TimeColumn::new_duration_secs(paths::TIME_TIMELINE, [time]),
            ],
            columns,
        )))
    }
}
