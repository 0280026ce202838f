//! Sweeps: the sweep library (`crawler_sweep`), as `crawler sweep PLAN --executor local` runs a
//! plan: the same points, the same store, the same Parquet file.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use pyo3::prelude::*;

use crawler_sweep::local::LocalOptions;
use crawler_sweep::plan::Plan;
use crawler_sweep::run::{Ending, Executor, Paths, Sweep};

use crate::{any_error, invalid, run_error};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    Ok(())
}

/// Runs `f` on a worker thread while this thread waits with the GIL released, checking Python's
/// signals every 100 ms: Ctrl-C sets the flag `f` is given (it should stop soon) and raises
/// `KeyboardInterrupt` once `f` has returned.
pub fn interruptible<T: Send>(
    py: Python<'_>,
    f: impl FnOnce(&AtomicBool) -> T + Send,
) -> PyResult<T> {
    let flag = AtomicBool::new(false);
    let (tx, rx) = crossbeam_channel::bounded::<T>(1);
    std::thread::scope(|s| {
        let flag = &flag;
        s.spawn(move || {
            let _ = tx.send(f(flag));
        });
        let mut pending: Option<PyErr> = None;
        loop {
            let got = py.detach(|| rx.recv_timeout(Duration::from_millis(100)));
            match got {
                Ok(v) => return pending.map_or(Ok(v), Err),
                Err(crossbeam_channel::RecvTimeoutError::Disconnected) => {
                    return Err(pending
                        .unwrap_or_else(|| run_error(py, "the worker thread panicked".into())))
                }
                Err(crossbeam_channel::RecvTimeoutError::Timeout) => {}
            }
            if pending.is_none() {
                if let Err(e) = py.check_signals() {
                    flag.store(true, Ordering::SeqCst);
                    pending = Some(e);
                }
            }
        }
    })
}

/// Runs the sweep plan at `plan` on `jobs` worker threads (default: all cores) with the results
/// kept in `store` and the table written to `out` (defaults as `crawler sweep`'s, under
/// `root`). Returns the Parquet file's path.
#[pyfunction]
#[pyo3(signature = (plan, out=None, store=None, jobs=None, retry_failed=false, root=PathBuf::from("out")))]
fn sweep(
    py: Python<'_>,
    plan: PathBuf,
    out: Option<PathBuf>,
    store: Option<PathBuf>,
    jobs: Option<usize>,
    retry_failed: bool,
    root: PathBuf,
) -> PyResult<PathBuf> {
    if jobs == Some(0) {
        return Err(invalid(py, "jobs", "0", "an integer >= 1"));
    }
    let plan = Plan::from_file(&plan).map_err(|e| any_error(py, e.into()))?;
    let d = Paths::defaults(&plan, &root);
    let paths = Paths {
        out: out.unwrap_or(d.out),
        store: store.unwrap_or(d.store),
        figures: d.figures,
        slurm: d.slurm,
    };
    let target = paths.out.clone();
    let sweep = Sweep::open(plan, paths).map_err(|e| any_error(py, e))?;
    let executor = Executor::Local(LocalOptions {
        jobs: jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
        progress: false,
    });
    let ending = interruptible(py, |flag| sweep.run(&executor, retry_failed, None, flag))?
        .map_err(|e| any_error(py, e))?;
    match ending {
        Ending::Complete { .. } => Ok(target),
        Ending::Interrupted { missing } => Err(run_error(
            py,
            format!("interrupted: {missing} points left (run again to resume)"),
        )),
        other => Err(run_error(
            py,
            format!("the sweep did not complete: {other:?}"),
        )),
    }
}
