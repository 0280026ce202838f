//! The Slurm executor: the missing points as one job array (`sbatch --array`), a chunk of points
//! per array task, each task appending its records to its own file; `collect` merges the task
//! files into the result store.
//!
//! A submission lives in its own folder `<work>/sub-NNN/`: `manifest.json` (the points, what to
//! evaluate, the chunk size, the code fingerprint), `job.sh`, `job_id`, and per array task
//! `task-<i>.jsonl` (one record per line, flushed per point) and `task-<i>.log`. The folder must
//! be on a file system the compute nodes share, and so must the `crawler-sweep` binary.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crawler_physics::scenario::{Overrides, Scenario};

use crate::evaluate::evaluate;
use crate::plan::Evaluate;
use crate::point::{cost, point_id, Point, CODE, FORMAT};
use crate::record::Record;
use crate::store::Store;

/// One point of a submission.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TaskPoint {
    /// Position in the plan.
    pub index: usize,
    /// The point's id (checked against the id the task computes).
    pub id: String,
    /// The resolved scenario (TOML).
    pub toml: String,
}

/// What the array tasks of one submission do.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    /// Result format.
    pub format: u32,
    /// Code fingerprint of the submitting binary.
    pub code: String,
    /// The plan's name.
    pub plan: String,
    /// What to evaluate.
    pub evaluate: Evaluate,
    /// Points per array task.
    pub chunk: usize,
    /// The points, in the order the tasks take them.
    pub points: Vec<TaskPoint>,
}

impl Manifest {
    /// Number of array tasks.
    pub fn tasks(&self) -> usize {
        self.points.len().div_ceil(self.chunk)
    }
}

/// Options of the Slurm executor.
#[derive(Debug, Clone, Default)]
pub struct SlurmOptions {
    /// Points per array task (default: at least 16, and few enough for at most 1000 tasks).
    pub chunk: Option<usize>,
    /// `--partition`.
    pub partition: Option<String>,
    /// `--time` (Slurm's time format, e.g. `00:30:00`), per array task.
    pub time: Option<String>,
    /// `--mem` (e.g. `1G`), per array task.
    pub mem: Option<String>,
    /// At most this many array tasks at once (`--array=...%N`).
    pub max_running: Option<usize>,
    /// More `sbatch` arguments, passed as they are (e.g. `--account=X`).
    pub sbatch_args: Vec<String>,
}

/// The default chunk for `n` points: at least 16 points per task (so that a task's start-up is
/// small against its work) and at most 1000 tasks (Slurm's default MaxArraySize is 1001).
pub fn default_chunk(n: usize) -> usize {
    n.div_ceil(1000).max(16)
}

/// Spreads `todo` over the array tasks so that they finish together; returns the chunk to
/// use and the points in the order the tasks take them (task t runs `[t * chunk, (t + 1) *
/// chunk)`). See [`deal_order`].
fn deal<'a>(todo: &[&'a Point], chunk: usize, spec: &Evaluate) -> (usize, Vec<&'a Point>) {
    let costs: Vec<f64> = todo.iter().map(|p| cost(p, spec)).collect();
    let (chunk, order) = deal_order(&costs, chunk);
    (chunk, order.into_iter().map(|i| todo[i]).collect())
}

/// The order in which array tasks of at most `chunk` points take points of the given
/// estimated costs: as many tasks as `chunk` asks for, the same number of points in each but
/// the last (the returned chunk, the smallest that keeps the number of tasks, so at most
/// `chunk`), the points dealt costliest first in snake order (task 0, 1, ..., T-1, T-1, ..., 0,
/// 0, 1, ...), ties in plan order. Neighbouring points of a plan often cost alike (a plant
/// run's cost grows with alpha, say), so contiguous chunks of the plan would leave one task
/// running long after the others.
fn deal_order(costs: &[f64], chunk: usize) -> (usize, Vec<usize>) {
    let n = costs.len();
    let tasks = n.div_ceil(chunk.max(1)).max(1);
    let chunk = n.div_ceil(tasks).max(1);
    let size = |t: usize| chunk.min(n - (t * chunk).min(n));
    let mut by_cost: Vec<usize> = (0..n).collect();
    by_cost.sort_by(|&a, &b| costs[b].total_cmp(&costs[a]).then(a.cmp(&b)));
    let mut slices: Vec<Vec<usize>> = (0..tasks).map(|t| Vec::with_capacity(size(t))).collect();
    let snake = (0..tasks).chain((0..tasks).rev()).cycle();
    let mut points = by_cost.into_iter().peekable();
    for t in snake {
        if points.peek().is_none() {
            break;
        }
        if slices[t].len() < size(t) {
            slices[t].extend(points.next());
        }
    }
    (chunk, slices.concat())
}

fn read_json<T: for<'a> Deserialize<'a>>(path: &Path) -> anyhow::Result<T> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| anyhow::anyhow!("{} is not valid: {e}", path.display()))
}

fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// A submitted job array.
#[derive(Debug, Clone)]
pub struct Submission {
    /// Its folder.
    pub dir: PathBuf,
    /// Slurm's job id.
    pub job_id: String,
    /// Array tasks.
    pub tasks: usize,
    /// Points.
    pub points: usize,
}

/// Submits `todo` as a job array under `work` (a new `sub-NNN` folder).
pub fn submit(
    work: &Path,
    plan_name: &str,
    todo: &[&Point],
    spec: &Evaluate,
    opts: &SlurmOptions,
) -> anyhow::Result<Submission> {
    let chunk = opts.chunk.unwrap_or_else(|| default_chunk(todo.len()));
    anyhow::ensure!(chunk >= 1, "invalid --chunk = 0: allowed an integer >= 1");
    let (chunk, todo) = deal(todo, chunk, spec);
    let work = std::path::absolute(work)?;
    std::fs::create_dir_all(&work)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", work.display()))?;
    let dir = (0..10_000)
        .map(|i| work.join(format!("sub-{i:03}")))
        .find(|d| std::fs::create_dir(d).is_ok())
        .ok_or_else(|| {
            anyhow::anyhow!("cannot create a submission folder in {}", work.display())
        })?;
    let manifest = Manifest {
        format: FORMAT,
        code: CODE.to_string(),
        plan: plan_name.to_string(),
        evaluate: spec.clone(),
        chunk,
        points: todo
            .iter()
            .map(|p| TaskPoint {
                index: p.index,
                id: p.id.clone(),
                toml: p.toml.clone(),
            })
            .collect(),
    };
    let mpath = dir.join("manifest.json");
    std::fs::write(&mpath, serde_json::to_vec(&manifest)?)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", mpath.display()))?;
    let exe = std::env::current_exe()?;
    let script = format!(
        "#!/bin/sh\n# One array task of the sweep {plan_name}: points [task * {chunk}, (task + 1) * {chunk}) of manifest.json.\n\
         exec {} task --manifest {} --task \"$SLURM_ARRAY_TASK_ID\"\n",
        quote(&exe.to_string_lossy()),
        quote(&mpath.to_string_lossy())
    );
    let jpath = dir.join("job.sh");
    std::fs::write(&jpath, script)?;
    let tasks = manifest.tasks();
    let mut array = format!("0-{}", tasks - 1);
    if let Some(m) = opts.max_running {
        array += &format!("%{m}");
    }
    let mut cmd = Command::new("sbatch");
    cmd.arg("--parsable")
        .arg(format!("--array={array}"))
        .arg(format!("--job-name=crawler-sweep-{plan_name}"))
        .arg(format!("--output={}", dir.join("task-%a.log").display()))
        .arg(format!("--chdir={}", dir.display()))
        .arg("--ntasks=1")
        .arg("--cpus-per-task=1");
    if let Some(p) = &opts.partition {
        cmd.arg(format!("--partition={p}"));
    }
    if let Some(t) = &opts.time {
        cmd.arg(format!("--time={t}"));
    }
    if let Some(m) = &opts.mem {
        cmd.arg(format!("--mem={m}"));
    }
    cmd.args(&opts.sbatch_args).arg(&jpath);
    let out = cmd.output().map_err(|e| {
        anyhow::anyhow!("cannot run sbatch ({e}): is Slurm installed and on PATH? (scripts/setup-slurm.sh installs it on Debian)")
    })?;
    anyhow::ensure!(
        out.status.success(),
        "sbatch refused the job array ({}): {}{}",
        out.status,
        String::from_utf8_lossy(&out.stderr).trim(),
        if tasks > 1000 {
            format!(" ({tasks} array tasks: a larger --chunk makes fewer)")
        } else {
            String::new()
        }
    );
    // --parsable prints "jobid" or "jobid;cluster"
    let job_id = String::from_utf8_lossy(&out.stdout)
        .trim()
        .split(';')
        .next()
        .unwrap_or_default()
        .to_string();
    anyhow::ensure!(
        !job_id.is_empty() && job_id.chars().all(|c| c.is_ascii_digit()),
        "sbatch printed no job id: {:?}",
        String::from_utf8_lossy(&out.stdout)
    );
    std::fs::write(dir.join("job_id"), format!("{job_id}\n"))?;
    Ok(Submission {
        dir,
        job_id,
        tasks,
        points: todo.len(),
    })
}

/// True while Slurm still lists the job (pending, running or completing).
pub fn job_active(job_id: &str) -> anyhow::Result<bool> {
    let out = Command::new("squeue")
        .args(["-h", "-o", "%i", "-j", job_id])
        .output()
        .map_err(|e| anyhow::anyhow!("cannot run squeue: {e}"))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        // a finished job that the controller already purged
        if err.contains("Invalid job id") {
            return Ok(false);
        }
        anyhow::bail!("squeue failed ({}): {}", out.status, err.trim());
    }
    Ok(!String::from_utf8_lossy(&out.stdout).trim().is_empty())
}

/// Complete lines (records) in the task files of a submission so far.
pub fn records_written(dir: &Path) -> usize {
    task_files(dir)
        .iter()
        .filter_map(|p| std::fs::read(p).ok())
        .map(|b| b.iter().filter(|c| **c == b'\n').count())
        .sum()
}

fn task_files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("task-") && n.ends_with(".jsonl"))
        })
        .collect();
    v.sort();
    v
}

/// Waits until the job leaves the queue, drawing a progress bar of the records written;
/// `Ok(false)` if `interrupt` was set first (the job keeps running).
pub fn wait(
    sub: &Submission,
    interrupt: &AtomicBool,
    progress: bool,
    poll: Duration,
) -> anyhow::Result<bool> {
    let target = if progress {
        indicatif::ProgressDrawTarget::stderr()
    } else {
        indicatif::ProgressDrawTarget::hidden()
    };
    let bar = indicatif::ProgressBar::with_draw_target(Some(sub.points as u64), target);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} slurm job {msg} [{bar:40}] {pos}/{len} points ({elapsed} elapsed, ETA {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(sub.job_id.clone());
    loop {
        bar.set_position(records_written(&sub.dir) as u64);
        if !job_active(&sub.job_id)? {
            bar.set_position(records_written(&sub.dir) as u64);
            bar.finish_and_clear();
            return Ok(true);
        }
        let until = std::time::Instant::now() + poll;
        while std::time::Instant::now() < until {
            if interrupt.load(Ordering::SeqCst) {
                bar.abandon();
                return Ok(false);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// What `collect` found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Collected {
    /// Submissions read.
    pub submissions: usize,
    /// Records added to the store.
    pub added: usize,
    /// Records already in the store.
    pub known: usize,
    /// Lines that were not a record of their submission (ignored, counted).
    pub rejected: usize,
    /// Jobs still in the queue.
    pub active_jobs: Vec<String>,
}

/// Merges every submission's task files under `work` into `store`.
pub fn collect(work: &Path, store: &Store, check_queue: bool) -> anyhow::Result<Collected> {
    let mut c = Collected::default();
    let mut subs: Vec<PathBuf> = match std::fs::read_dir(work) {
        Ok(rd) => rd
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.join("manifest.json").is_file())
            .collect(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => anyhow::bail!("cannot read {}: {e}", work.display()),
    };
    subs.sort();
    for dir in subs {
        let manifest: Manifest = read_json(&dir.join("manifest.json"))?;
        let ids: std::collections::HashSet<&str> =
            manifest.points.iter().map(|p| p.id.as_str()).collect();
        c.submissions += 1;
        if check_queue {
            if let Ok(id) = std::fs::read_to_string(dir.join("job_id")) {
                let id = id.trim().to_string();
                if job_active(&id).unwrap_or(false) {
                    c.active_jobs.push(id);
                }
            }
        }
        for f in task_files(&dir) {
            let file = std::fs::File::open(&f)
                .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", f.display()))?;
            let mut reader = std::io::BufReader::new(file);
            let mut line = String::new();
            loop {
                line.clear();
                let n = reader.read_line(&mut line)?;
                // no line, or a last line cut off by a killed task: not a record
                if n == 0 || !line.ends_with('\n') {
                    break;
                }
                match serde_json::from_str::<Record>(&line) {
                    Ok(rec) if ids.contains(rec.id.as_str()) && rec.format == FORMAT => {
                        if store.contains(&rec.id) {
                            c.known += 1;
                        } else {
                            store.put(&rec)?;
                            c.added += 1;
                        }
                    }
                    _ => c.rejected += 1,
                }
            }
        }
    }
    Ok(c)
}

/// Runs array task `task` of the submission whose manifest is at `manifest_path`: its chunk of
/// points, one after the other, each record appended to `task-<task>.jsonl` beside the manifest
/// as soon as it is done. Points already in that file (a requeued task) are skipped.
pub fn run_task(manifest_path: &Path, task: usize) -> anyhow::Result<usize> {
    let manifest: Manifest = read_json(manifest_path)?;
    anyhow::ensure!(
        manifest.format == FORMAT && manifest.code == CODE,
        "this crawler-sweep (format {FORMAT}, code {CODE}) is not the one that submitted {} (format {}, code {}): \
         the nodes must run the same build",
        manifest_path.display(),
        manifest.format,
        manifest.code
    );
    anyhow::ensure!(
        task < manifest.tasks(),
        "invalid --task = {task}: allowed 0 <= task < {} (the array's size)",
        manifest.tasks()
    );
    let dir = manifest_path.parent().unwrap_or(Path::new("."));
    let out_path = dir.join(format!("task-{task}.jsonl"));
    let mut done = std::collections::HashSet::new();
    if let Ok(text) = std::fs::read_to_string(&out_path) {
        for line in text.split_inclusive('\n').filter(|l| l.ends_with('\n')) {
            if let Ok(r) = serde_json::from_str::<Record>(line) {
                done.insert(r.id);
            }
        }
        // drop a cut-off last line so that appends start on a fresh line
        if !text.is_empty() && !text.ends_with('\n') {
            let keep = text.rfind('\n').map_or(0, |i| i + 1);
            std::fs::write(&out_path, &text[..keep])?;
        }
    }
    let mut out = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&out_path)
        .map_err(|e| anyhow::anyhow!("cannot open {}: {e}", out_path.display()))?;
    let lo = task * manifest.chunk;
    let hi = (lo + manifest.chunk).min(manifest.points.len());
    let mut n = 0;
    for tp in &manifest.points[lo..hi] {
        if done.contains(&tp.id) {
            continue;
        }
        let scenario = Scenario::from_toml(
            &tp.toml,
            &format!("point {}", tp.index),
            &Overrides::default(),
        )?;
        let id = point_id(&scenario, &manifest.evaluate);
        anyhow::ensure!(
            id == tp.id,
            "point {} resolves to id {id} here but {} when submitted: the nodes must run the same build",
            tp.index,
            tp.id
        );
        let point = Point {
            index: tp.index,
            assignments: Vec::new(),
            toml: tp.toml.clone(),
            scenario,
            id,
        };
        let rec = evaluate(&point, &manifest.evaluate);
        let mut line = serde_json::to_vec(&rec)?;
        line.push(b'\n');
        out.write_all(&line)?;
        out.flush()?;
        n += 1;
        eprintln!(
            "point {} done in {:.3} s{}",
            tp.index,
            rec.wall_time,
            rec.error
                .as_deref()
                .map(|e| format!(" (failed: {e})"))
                .unwrap_or_default()
        );
    }
    Ok(n)
}

/// The last lines of the logs of tasks that wrote fewer records than their chunk, for messages.
pub fn failed_task_logs(work: &Path, store: &Store, max_lines: usize) -> Vec<String> {
    let mut out = Vec::new();
    let Ok(rd) = std::fs::read_dir(work) else {
        return out;
    };
    let mut subs: Vec<PathBuf> = rd.flatten().map(|e| e.path()).collect();
    subs.sort();
    for dir in subs {
        let Ok(m) = read_json::<Manifest>(&dir.join("manifest.json")) else {
            continue;
        };
        for t in 0..m.tasks() {
            let lo = t * m.chunk;
            let hi = (lo + m.chunk).min(m.points.len());
            if m.points[lo..hi].iter().all(|p| store.contains(&p.id)) {
                continue;
            }
            let log = dir.join(format!("task-{t}.log"));
            let tail = std::fs::read_to_string(&log)
                .map(|s| {
                    let lines: Vec<&str> = s.lines().collect();
                    lines[lines.len().saturating_sub(max_lines)..].join("\n")
                })
                .unwrap_or_else(|_| "(no log)".into());
            out.push(format!("{} task {t}:\n{tail}", dir.display()));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::deal_order;

    #[test]
    fn dealing_keeps_every_point_once_and_the_number_of_tasks() {
        for n in 1usize..40 {
            for chunk in 1..12 {
                let costs: Vec<f64> = (0..n).map(|i| ((i * 7) % 5) as f64).collect();
                let (c, order) = deal_order(&costs, chunk);
                assert!(c <= chunk, "n {n} chunk {chunk}: {c}");
                assert_eq!(n.div_ceil(c), n.div_ceil(chunk), "n {n} chunk {chunk}");
                let mut sorted = order.clone();
                sorted.sort();
                assert_eq!(sorted, (0..n).collect::<Vec<_>>(), "n {n} chunk {chunk}");
            }
        }
    }

    #[test]
    fn a_cost_that_grows_along_the_plan_is_shared_evenly() {
        // cost rising with the plan's index (as with alpha): contiguous halves would give
        // 300^2 against 3 x 300^2; dealt, the two tasks' totals differ by under 1 %
        let costs: Vec<f64> = (0..600).map(|i| i as f64).collect();
        let (chunk, order) = deal_order(&costs, 300);
        assert_eq!(chunk, 300);
        let total = |t: usize| -> f64 {
            order[t * chunk..(t + 1) * chunk]
                .iter()
                .map(|&i| costs[i])
                .sum()
        };
        let (a, b) = (total(0), total(1));
        assert!((a - b).abs() < 0.01 * a.min(b), "{a} against {b}");
        // the costliest points go first, so the last points each task runs are its cheapest
        assert_eq!(order[0], 599);
        assert_eq!(order[chunk], 598);
    }

    #[test]
    fn chunks_are_evened_out_without_adding_tasks() {
        // 600 points in chunks of 250: three tasks of 200, not 250, 250, 100
        let (chunk, order) = deal_order(&[1.0; 600], 250);
        assert_eq!((chunk, order.len()), (200, 600));
        // equal costs: plan order dealt round the tasks, so each task spans the whole plan
        assert_eq!(&order[..3], &[0, 5, 6]);
    }
}
