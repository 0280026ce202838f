//! A sweep from plan to Parquet: resolve the points, find those missing from the store, run them
//! (locally or on Slurm), and write the table, the figures and the recording once every point
//! has a record.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::local::{run_local, LocalOptions};
use crate::plan::Plan;
use crate::point::{resolve, Point};
use crate::record::Record;
use crate::slurm::{self, SlurmOptions};
use crate::store::Store;
use crate::table;

/// Where a sweep keeps its files.
#[derive(Debug, Clone)]
pub struct Paths {
    /// The Parquet file.
    pub out: PathBuf,
    /// The result store (shared by plans).
    pub store: PathBuf,
    /// Figures and the recording (plans with `[figures]`).
    pub figures: PathBuf,
    /// Slurm submissions.
    pub slurm: PathBuf,
}

impl Paths {
    /// The defaults for `plan` under `root` (`out/` of the current folder): `sweeps/<name>.parquet`,
    /// `sweep-store/`, `sweeps/<name>/` and `sweeps/<name>.slurm/`.
    pub fn defaults(plan: &Plan, root: &Path) -> Self {
        Self {
            out: root.join("sweeps").join(format!("{}.parquet", plan.name)),
            store: root.join("sweep-store"),
            figures: root.join("sweeps").join(&plan.name),
            slurm: root.join("sweeps").join(format!("{}.slurm", plan.name)),
        }
    }
}

/// What a program draws of a plan's maps (figures, a recording) into a folder, returning the
/// files written; the library computes the maps ([`crate::maps::Maps`]) and draws nothing.
pub trait MapOutputs {
    /// Writes the maps of `plan` into `dir`.
    fn write(
        &self,
        plan: &Plan,
        maps: &crate::maps::Maps,
        dir: &Path,
    ) -> anyhow::Result<Vec<PathBuf>>;
}

/// The executor of a sweep.
#[derive(Debug, Clone)]
pub enum Executor {
    /// This machine's cores.
    Local(LocalOptions),
    /// A Slurm job array; `wait` polls the queue until it is done, then collects.
    Slurm {
        /// sbatch options.
        options: SlurmOptions,
        /// Wait for the job and collect.
        wait: bool,
        /// Queue polling interval.
        poll: Duration,
        /// Progress bar while waiting.
        progress: bool,
    },
}

/// How a sweep command ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// Every point has a record; the table (and figures) were written.
    Complete {
        /// Points evaluated by this command.
        evaluated: usize,
        /// Points whose evaluation failed (kept with their error).
        failed: usize,
    },
    /// Interrupted: the finished points are stored, rerunning the command resumes.
    Interrupted {
        /// Points still missing.
        missing: usize,
    },
    /// Submitted to Slurm without waiting (or the wait was interrupted).
    Submitted {
        /// The job id.
        job_id: String,
    },
    /// Some points have no record (Slurm tasks that failed); rerunning submits them again.
    Incomplete {
        /// Points still missing.
        missing: usize,
        /// The failed tasks' log tails.
        logs: Vec<String>,
    },
}

/// Resolved plan, its points and the store.
pub struct Sweep {
    /// The plan.
    pub plan: Plan,
    /// Its points, in plan order.
    pub points: Vec<Point>,
    /// The store.
    pub store: Store,
    /// Output paths.
    pub paths: Paths,
}

impl Sweep {
    /// Loads and resolves a plan (every point validated by the scenario parser).
    pub fn open(plan: Plan, paths: Paths) -> anyhow::Result<Self> {
        let points = resolve(&plan)?;
        let store = Store::open(&paths.store)?;
        Ok(Self {
            plan,
            points,
            store,
            paths,
        })
    }

    /// The points without a record (with `retry_failed`, also those whose record has an error).
    pub fn missing(&self, retry_failed: bool) -> anyhow::Result<Vec<&Point>> {
        let mut v = Vec::new();
        for p in &self.points {
            let needed = if retry_failed {
                match self.store.get(&p.id)? {
                    None => true,
                    Some(r) => r.error.is_some(),
                }
            } else {
                !self.store.contains(&p.id)
            };
            if needed {
                v.push(p);
            }
        }
        Ok(v)
    }

    /// Every point's record, in plan order, if all are stored.
    pub fn records(&self) -> anyhow::Result<Option<Vec<Record>>> {
        let mut v = Vec::with_capacity(self.points.len());
        for p in &self.points {
            match self.store.get(&p.id)? {
                Some(r) => v.push(r),
                None => return Ok(None),
            }
        }
        Ok(Some(v))
    }

    /// Writes the Parquet file, and, if the plan asks for maps and `maps` draws them, the maps
    /// (figures, a recording).
    pub fn write_outputs(
        &self,
        records: &[Record],
        maps: Option<&dyn MapOutputs>,
    ) -> anyhow::Result<Vec<PathBuf>> {
        let batch = table::batch(&self.plan, &self.points, records)?;
        table::write_parquet(&self.plan, &batch, &self.paths.out)?;
        let mut written = vec![self.paths.out.clone()];
        if let (Some(out), Some(f)) = (maps, &self.plan.figures) {
            let built = crate::maps::Maps::build(&self.plan, f, &self.points, records)?;
            written.extend(out.write(&self.plan, &built, &self.paths.figures)?);
        }
        Ok(written)
    }

    /// Runs the missing points with `executor`; writes the outputs when all are done.
    pub fn run(
        &self,
        executor: &Executor,
        retry_failed: bool,
        maps: Option<&dyn MapOutputs>,
        interrupt: &AtomicBool,
    ) -> anyhow::Result<Ending> {
        let todo = self.missing(retry_failed)?;
        let n = self.points.len();
        eprintln!(
            "crawler-sweep: plan {} ({}): {n} points, {} stored, {} to run",
            self.plan.name,
            self.plan.origin,
            n - todo.len(),
            todo.len()
        );
        for (caveat, count) in crate::point::caveats(&self.points) {
            eprintln!("crawler-sweep: warning: {count} of {n} points: {caveat}");
        }
        let started = Instant::now();
        let mut evaluated = 0;
        let mut failed_now = 0;
        if !todo.is_empty() {
            match executor {
                Executor::Local(opts) => {
                    eprintln!("crawler-sweep: local executor, {} workers", opts.jobs);
                    let o = run_local(&todo, &self.plan.evaluate, &self.store, *opts, interrupt)?;
                    evaluated = o.done;
                    failed_now = o.failed;
                    if let Some(e) = o.store_errors.first() {
                        anyhow::bail!("{e} ({} points stored before that)", o.done);
                    }
                    if o.left > 0 {
                        eprintln!(
                            "crawler-sweep: interrupted after {} points in {:.1} s; {} points left; \
                             the finished ones are stored in {}: run the same command again to resume",
                            o.done,
                            started.elapsed().as_secs_f64(),
                            o.left,
                            self.store.dir().display()
                        );
                        return Ok(Ending::Interrupted { missing: o.left });
                    }
                }
                Executor::Slurm {
                    options,
                    wait,
                    poll,
                    progress,
                } => {
                    // results of an earlier submission that finished since: merge them first
                    slurm::collect(&self.paths.slurm, &self.store, false)?;
                    let todo = self.missing(retry_failed)?;
                    if !todo.is_empty() {
                        let sub = slurm::submit(
                            &self.paths.slurm,
                            &self.plan.name,
                            &todo,
                            &self.plan.evaluate,
                            options,
                        )?;
                        eprintln!(
                            "crawler-sweep: submitted job {} ({} array tasks of up to {} points) from {}",
                            sub.job_id,
                            sub.tasks,
                            sub.points.div_ceil(sub.tasks),
                            sub.dir.display()
                        );
                        if !*wait {
                            eprintln!(
                                "crawler-sweep: when it has finished: crawler sweep collect {}",
                                self.plan.origin
                            );
                            return Ok(Ending::Submitted { job_id: sub.job_id });
                        }
                        if !slurm::wait(&sub, interrupt, *progress, *poll)? {
                            eprintln!(
                                "crawler-sweep: stopped waiting; job {} keeps running (scancel {} cancels it); \
                                 collect its results later with: crawler sweep collect {}",
                                sub.job_id, sub.job_id, self.plan.origin
                            );
                            return Ok(Ending::Submitted { job_id: sub.job_id });
                        }
                        let c = slurm::collect(&self.paths.slurm, &self.store, false)?;
                        evaluated = c.added;
                    }
                }
            }
        }
        self.finish(evaluated, failed_now, maps, started)
    }

    /// Merges Slurm task files into the store, then writes the outputs if every point is there.
    pub fn collect(&self, maps: Option<&dyn MapOutputs>) -> anyhow::Result<Ending> {
        let started = Instant::now();
        let c = slurm::collect(&self.paths.slurm, &self.store, true)?;
        eprintln!(
            "crawler-sweep: {} submissions in {}: {} records added to the store, {} known, {} lines rejected",
            c.submissions,
            self.paths.slurm.display(),
            c.added,
            c.known,
            c.rejected
        );
        if !c.active_jobs.is_empty() {
            eprintln!(
                "crawler-sweep: jobs still queued or running: {}",
                c.active_jobs.join(", ")
            );
        }
        self.finish(c.added, 0, maps, started)
    }

    fn finish(
        &self,
        evaluated: usize,
        failed_now: usize,
        maps: Option<&dyn MapOutputs>,
        started: Instant,
    ) -> anyhow::Result<Ending> {
        let Some(records) = self.records()? else {
            let missing = self.missing(false)?.len();
            let logs = slurm::failed_task_logs(&self.paths.slurm, &self.store, 5);
            return Ok(Ending::Incomplete { missing, logs });
        };
        let failed = records.iter().filter(|r| r.error.is_some()).count();
        let written = self.write_outputs(&records, maps)?;
        let secs = started.elapsed().as_secs_f64();
        eprintln!(
            "crawler-sweep: {} points evaluated in {secs:.1} s{}; {} of {} points failed (column error){}",
            evaluated,
            if evaluated > 0 {
                format!(" ({:.3} s per point)", secs / evaluated as f64)
            } else {
                String::new()
            },
            failed,
            records.len(),
            if failed > 0 { "; --retry-failed runs them again" } else { "" }
        );
        for w in &written {
            println!("{}", w.display());
        }
        Ok(Ending::Complete {
            evaluated,
            failed: failed_now,
        })
    }
}
