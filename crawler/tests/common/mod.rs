//! Helpers of the sweep tests: plans in temporary folders, the real binary, Parquet read back.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Arc;

use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch, StringArray};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

/// The repository's root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
        .to_path_buf()
}

/// The `crawler-sweep` binary of this build.
pub fn sweep_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_crawler-sweep"))
}

/// A plan file in `dir` whose base is the repository's paper scenario; `body` follows `name`.
pub fn write_plan(dir: &Path, name: &str, body: &str) -> PathBuf {
    let scenario = repo_root().join("scenarios/paper.toml");
    let text = format!(
        "name = \"{name}\"\nscenario = {:?}\n{body}",
        scenario.display().to_string()
    );
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `crawler-sweep ARGS` in `dir` (bounded by the caller's plan size), returns its output.
pub fn sweep(dir: &Path, args: &[&str]) -> Output {
    Command::new(sweep_bin())
        .args(args)
        .current_dir(dir)
        .output()
        .expect("crawler-sweep runs")
}

/// Stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The Parquet file as one batch.
pub fn read_parquet(path: &Path) -> RecordBatch {
    let f = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let reader = ParquetRecordBatchReaderBuilder::try_new(f)
        .unwrap()
        .build()
        .unwrap();
    let batches: Vec<RecordBatch> = reader.map(|b| b.unwrap()).collect();
    arrow_select_concat(&batches)
}

fn arrow_select_concat(batches: &[RecordBatch]) -> RecordBatch {
    assert!(!batches.is_empty(), "no rows");
    if batches.len() == 1 {
        return batches[0].clone();
    }
    let schema = batches[0].schema();
    let cols: Vec<ArrayRef> = (0..schema.fields().len())
        .map(|i| {
            let parts: Vec<&dyn Array> = batches.iter().map(|b| b.column(i).as_ref()).collect();
            arrow_select::concat::concat(&parts).unwrap()
        })
        .collect();
    RecordBatch::try_new(Arc::clone(&schema), cols).unwrap()
}

/// A Float64 column by name.
pub fn f64s(b: &RecordBatch, name: &str) -> Vec<Option<f64>> {
    let c = b
        .column_by_name(name)
        .unwrap_or_else(|| panic!("no column {name}"));
    let a = c.as_any().downcast_ref::<Float64Array>().expect("Float64");
    (0..a.len())
        .map(|i| (!a.is_null(i)).then(|| a.value(i)))
        .collect()
}

/// A Utf8 column by name.
pub fn strs(b: &RecordBatch, name: &str) -> Vec<Option<String>> {
    let c = b
        .column_by_name(name)
        .unwrap_or_else(|| panic!("no column {name}"));
    let a = c.as_any().downcast_ref::<StringArray>().expect("Utf8");
    (0..a.len())
        .map(|i| (!a.is_null(i)).then(|| a.value(i).to_string()))
        .collect()
}

/// Asserts that two result files hold the same table: same schema and metadata, and every column
/// but `wall_time` equal bit for bit (floats compared by their bits, nulls by position).
pub fn assert_same_results(a: &Path, b: &Path) {
    let (x, y) = (read_parquet(a), read_parquet(b));
    assert_eq!(x.schema(), y.schema(), "schemas differ");
    assert_eq!(x.num_rows(), y.num_rows(), "row counts differ");
    let mut compared = 0;
    for (i, field) in x.schema().fields().iter().enumerate() {
        if field.name() == "wall_time" {
            continue;
        }
        let (ca, cb) = (x.column(i), y.column(i));
        if let Some(fa) = ca.as_any().downcast_ref::<Float64Array>() {
            let fb = cb.as_any().downcast_ref::<Float64Array>().unwrap();
            for r in 0..fa.len() {
                assert_eq!(
                    fa.is_null(r),
                    fb.is_null(r),
                    "{} row {r}: null differs",
                    field.name()
                );
                if !fa.is_null(r) {
                    assert_eq!(
                        fa.value(r).to_bits(),
                        fb.value(r).to_bits(),
                        "{} row {r}: {} vs {}",
                        field.name(),
                        fa.value(r),
                        fb.value(r)
                    );
                }
            }
        } else {
            assert_eq!(
                ca.to_data(),
                cb.to_data(),
                "column {} differs",
                field.name()
            );
        }
        compared += 1;
    }
    assert!(compared > 10, "only {compared} columns compared");
    // the file-level metadata (plan, format, code) is equal too: no timestamps
    let md = |p: &Path| {
        let f = std::fs::File::open(p).unwrap();
        let r = ParquetRecordBatchReaderBuilder::try_new(f).unwrap();
        r.metadata().file_metadata().key_value_metadata().cloned()
    };
    assert_eq!(md(a), md(b), "key-value metadata differs");
}

/// Record files in a store.
pub fn stored(store: &Path) -> usize {
    let Ok(rd) = std::fs::read_dir(store) else {
        return 0;
    };
    rd.flatten()
        .filter(|e| e.path().is_dir())
        .flat_map(|e| std::fs::read_dir(e.path()).into_iter().flatten().flatten())
        .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
        .count()
}

/// The Python of the project's venv (with pyarrow), installed beforehand by scripts/setup.sh; a
/// test never installs packages itself, and says which step is missing.
pub fn python() -> PathBuf {
    let p = repo_root().join(".venv/bin/python");
    assert!(
        p.is_file() && repo_root().join(".venv/.installed").is_file(),
        "the tests need the project's Python venv with its pinned packages: run scripts/setup.sh once"
    );
    p
}
