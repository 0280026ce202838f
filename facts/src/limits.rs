//! The sizes every input is bounded by, whichever route it comes in by (scenario file, flag,
//! wire message, checkpoint, FMI call, Python argument).

/// Most cells a plant may have (every field is an array of this many numbers at most).
pub const MAX_CELLS: usize = 1 << 20;

/// Longest identifier (run id, process id, model or policy name), bytes.
pub const MAX_ID_LEN: usize = 128;

/// Longest scenario name, bytes (it travels in the plant's final report).
pub const MAX_SCENARIO_NAME_LEN: usize = MAX_ID_LEN;
