//! The local executor: the missing points on all cores of this machine (a rayon pool), the
//! costliest first, each stored as soon as it is done. An interrupt stops starting new points;
//! those running finish and are kept.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use crate::evaluate::evaluate;
use crate::plan::Evaluate;
use crate::point::{cost, Point};
use crate::store::Store;

/// How a local run ended.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LocalOutcome {
    /// Points evaluated and stored in this run.
    pub done: usize,
    /// Of those, points whose evaluation failed (kept with their error).
    pub failed: usize,
    /// Points left because of an interrupt.
    pub left: usize,
    /// Errors storing records (the points are not stored; the run stops starting new ones).
    pub store_errors: Vec<String>,
}

/// Options of the local executor.
#[derive(Debug, Clone, Copy)]
pub struct LocalOptions {
    /// Worker threads (default: all cores).
    pub jobs: usize,
    /// Draw a progress bar on stderr (only when it is a terminal).
    pub progress: bool,
}

/// Evaluates `todo` (points missing from `store`) with `opts.jobs` workers; `interrupt` set to
/// true stops starting new points.
pub fn run_local(
    todo: &[&Point],
    spec: &Evaluate,
    store: &Store,
    opts: LocalOptions,
    interrupt: &AtomicBool,
) -> anyhow::Result<LocalOutcome> {
    // Longest first (by estimated cost): the last points to finish are short ones, so the
    // workers finish together.
    let mut order: Vec<(f64, &Point)> = todo.iter().map(|p| (cost(p, spec), *p)).collect();
    order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.index.cmp(&b.1.index)));
    let total_cost: f64 = order.iter().map(|(c, _)| c).sum();
    let bar = progress_bar(opts.progress, order.len(), total_cost);
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let failed = AtomicUsize::new(0);
    let store_errors = Mutex::new(Vec::new());
    let stop = AtomicBool::new(false);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.jobs.max(1))
        .thread_name(|i| format!("sweep-worker-{i}"))
        .build()?;
    pool.scope(|s| {
        for _ in 0..opts.jobs.max(1) {
            s.spawn(|_| loop {
                if interrupt.load(Ordering::SeqCst) || stop.load(Ordering::SeqCst) {
                    break;
                }
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some((c, point)) = order.get(i) else {
                    break;
                };
                let rec = evaluate(point, spec);
                if rec.error.is_some() {
                    failed.fetch_add(1, Ordering::SeqCst);
                }
                match store.put(&rec) {
                    Ok(()) => {
                        let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                        bar.inc(c.round() as u64);
                        bar.set_message(format!("{n}/{} points", order.len()));
                    }
                    Err(e) => {
                        store_errors
                            .lock()
                            .expect("not poisoned")
                            .push(e.to_string());
                        stop.store(true, Ordering::SeqCst);
                    }
                }
            });
        }
    });
    bar.finish_and_clear();
    let done = done.into_inner();
    Ok(LocalOutcome {
        done,
        failed: failed.into_inner(),
        left: order.len() - done,
        store_errors: store_errors.into_inner().expect("not poisoned"),
    })
}

/// A progress bar over the points' estimated cost (so its ETA holds although the longest
/// points run first), hidden when stderr is not a terminal or `show` is false.
fn progress_bar(show: bool, points: usize, total_cost: f64) -> indicatif::ProgressBar {
    let target = if show {
        indicatif::ProgressDrawTarget::stderr()
    } else {
        indicatif::ProgressDrawTarget::hidden()
    };
    let bar = indicatif::ProgressBar::with_draw_target(Some(total_cost.round() as u64), target);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} sweep [{bar:40}] {msg} ({elapsed} elapsed, ETA {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(format!("0/{points} points"));
    bar.enable_steady_tick(Duration::from_millis(250));
    bar
}
