//! The grid's axes and the parallel map over its cells.

/// `n` evenly spaced values from `a` to `b` inclusive.
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    if n == 1 {
        return vec![a];
    }
    (0..n)
        .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
        .collect()
}

static THREADS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Limits the threads of [`parallel_map`] (0: all cores).
pub fn set_threads(n: usize) {
    THREADS.store(n, std::sync::atomic::Ordering::Relaxed);
}

/// Maps `f` over `items` on all cores (or [`set_threads`]), preserving order.
pub fn parallel_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    parallel_map_range(items.len(), |i| f(&items[i]))
}

/// `f(0), f(1), ..., f(n - 1)` computed on all cores (or [`set_threads`]), in order, written in
/// place (a grid's report holds a quarter of a million cells).
pub fn parallel_map_range<R: Send>(n: usize, f: impl Fn(usize) -> R + Sync) -> Vec<R> {
    use rayon::prelude::*;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let limit = THREADS.load(std::sync::atomic::Ordering::Relaxed);
    let threads = (if limit == 0 { cores } else { limit.min(cores) }).min(n.max(1));
    if threads <= 1 || n < 64 {
        return (0..n).map(f).collect();
    }
    let map = || (0..n).into_par_iter().map(&f).collect();
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool.install(map),
        // no threads to be had: the work is the same on this one
        Err(_) => (0..n).map(&f).collect(),
    }
}
