//! The Slurm executor against a real single-node Slurm cluster that this test starts itself
//! (Debian's slurmctld, slurmd and munged, installed beforehand by scripts/setup.sh): its own
//! munge key and socket, a slurm.conf in a temporary folder with free loopback ports, every
//! daemon stopped at the end. If Slurm is not installed or cannot start, the test fails and says
//! why (it never installs anything itself).
//!
//! Rows carry the wall time each point took, which differs between runs; every other column is
//! compared bit for bit (`assert_same_results`), and so is the file's metadata.

mod common;

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::*;

/// A daemon started by the test; killed (and reaped) on drop.
struct Daemon {
    name: &'static str,
    child: Child,
}

impl Drop for Daemon {
    fn drop(&mut self) {
        unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        eprintln!("{} did not stop on SIGTERM within 5 s; killed", self.name);
    }
}

/// A single-node cluster: munged, slurmctld, slurmd (dropped in reverse order).
struct Cluster {
    _daemons: Vec<Daemon>,
    dir: tempfile::TempDir,
    conf: PathBuf,
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn tail(path: &Path) -> String {
    let s = std::fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(15)..].join("\n")
}

fn sbin(name: &str) -> PathBuf {
    for d in ["/usr/sbin", "/usr/bin", "/usr/local/sbin", "/usr/local/bin"] {
        let p = Path::new(d).join(name);
        if p.is_file() {
            return p;
        }
    }
    PathBuf::from(name)
}

/// Fails the test, saying what is missing and how to get it, unless Slurm's daemons and
/// commands and MUNGE are installed.
fn assert_slurm_is_installed() {
    let missing: Vec<&str> = [
        "slurmctld",
        "slurmd",
        "sbatch",
        "squeue",
        "scancel",
        "munged",
    ]
    .into_iter()
    .filter(|c| !sbin(c).is_file())
    .collect();
    assert!(
        missing.is_empty(),
        "this test needs Slurm and MUNGE (missing: {}): run scripts/setup.sh once \
         (it installs Debian's slurmctld, slurmd, slurm-client and munge; needs root or sudo)",
        missing.join(", ")
    );
}

/// Starts `cmd` as the daemon `name`, its standard streams closed.
fn spawn_daemon(name: &'static str, cmd: &mut Command) -> Daemon {
    let child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| {
            panic!("cannot start {name}: {e} (is Slurm installed? run scripts/setup.sh)")
        });
    Daemon { name, child }
}

/// Starts munged with a new key of its own in `d`, listening on `socket`, and waits (at most
/// 10 s) until the socket exists.
fn start_munged(d: &Path, socket: &Path) -> Daemon {
    // munge: our own key and socket (the key must be private to its owner)
    let mut key = vec![0u8; 1024];
    std::io::Read::read_exact(&mut std::fs::File::open("/dev/urandom").unwrap(), &mut key).unwrap();
    let key_path = d.join("munge.key");
    std::fs::write(&key_path, key).unwrap();
    std::fs::set_permissions(
        &key_path,
        std::os::unix::fs::PermissionsExt::from_mode(0o400),
    )
    .unwrap();
    let munged = spawn_daemon(
        "munged",
        Command::new(sbin("munged"))
            .arg("--foreground")
            .arg("--force")
            .arg(format!("--socket={}", socket.display()))
            .arg(format!("--key-file={}", key_path.display()))
            .arg(format!("--log-file={}", d.join("munged.log").display()))
            .arg(format!("--pid-file={}", d.join("munged.pid").display()))
            .arg(format!("--seed-file={}", d.join("munged.seed").display())),
    );
    let deadline = Instant::now() + Duration::from_secs(10);
    while !socket.exists() {
        assert!(
            Instant::now() < deadline,
            "munged did not create its socket:\n{}",
            tail(&d.join("munged.log"))
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    munged
}

/// Writes the cluster's `slurm.conf` in `d` (this host as its one node, with all its CPUs, on
/// free loopback ports; MUNGE on `socket`) and returns its path.
fn write_slurm_conf(d: &Path, socket: &Path) -> PathBuf {
    let host = String::from_utf8(Command::new("hostname").arg("-s").output().unwrap().stdout)
        .unwrap()
        .trim()
        .to_string();
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let conf = d.join("slurm.conf");
    let text = format!(
        "ClusterName=crawlertest\n\
         SlurmctldHost={host}(127.0.0.1)\n\
         SlurmctldPort={ctld}\n\
         SlurmdPort={slurmd}\n\
         AuthType=auth/munge\n\
         AuthInfo=socket={socket}\n\
         CredType=cred/munge\n\
         SlurmUser=root\n\
         SlurmdUser=root\n\
         StateSaveLocation={d}/state\n\
         SlurmdSpoolDir={d}/spool\n\
         SlurmctldPidFile={d}/slurmctld.pid\n\
         SlurmdPidFile={d}/slurmd.pid\n\
         SlurmctldLogFile={d}/slurmctld.log\n\
         SlurmdLogFile={d}/slurmd.log\n\
         ProctrackType=proctrack/linuxproc\n\
         TaskPlugin=task/none\n\
         SelectType=select/cons_tres\n\
         SelectTypeParameters=CR_Core_Memory\n\
         DefMemPerCPU=100\n\
         SchedulerType=sched/builtin\n\
         SchedulerParameters=batch_sched_delay=0,sched_min_interval=0\n\
         JobAcctGatherType=jobacct_gather/none\n\
         AccountingStorageType=accounting_storage/none\n\
         MpiDefault=none\n\
         ReturnToService=2\n\
         NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} RealMemory=1000 State=UNKNOWN\n\
         PartitionName=sweeptest Nodes={host} Default=YES MaxTime=INFINITE State=UP\n",
        ctld = free_port(),
        slurmd = free_port(),
        socket = socket.display(),
        d = d.display(),
    );
    std::fs::write(&conf, text).unwrap();
    conf
}

impl Cluster {
    fn logs(&self) -> String {
        ["munged.log", "slurmctld.log", "slurmd.log"]
            .iter()
            .map(|f| format!("--- {f}:\n{}", tail(&self.dir.path().join(f))))
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Starts munged, slurmctld and slurmd in a new temporary folder and waits (bounded) until
    /// the node is idle.
    fn start() -> Cluster {
        // Slurm is a prerequisite installed by scripts/setup.sh (which runs scripts/setup-slurm.sh),
        // never from inside the test: say what is missing and how to get it.
        assert_slurm_is_installed();
        let dir = tempfile::Builder::new()
            .prefix("crawler-slurm")
            .tempdir()
            .unwrap();
        let d = dir.path();
        for sub in ["state", "spool"] {
            std::fs::create_dir(d.join(sub)).unwrap();
        }
        let socket = d.join("munge.socket");
        let mut daemons = Vec::new();
        daemons.push(start_munged(d, &socket));
        let conf = write_slurm_conf(d, &socket);
        daemons.push(spawn_daemon(
            "slurmctld",
            Command::new(sbin("slurmctld"))
                .arg("-D")
                .arg("-f")
                .arg(&conf)
                .env("SLURM_CONF", &conf),
        ));
        daemons.push(spawn_daemon(
            "slurmd",
            Command::new(sbin("slurmd"))
                .arg("-D")
                .arg("-f")
                .arg(&conf)
                .env("SLURM_CONF", &conf),
        ));
        let cluster = Cluster {
            _daemons: daemons,
            dir,
            conf,
        };
        cluster.wait_until_idle();
        cluster
    }

    /// Waits (at most 60 s, polling `sinfo` every 200 ms) until the node is idle.
    fn wait_until_idle(&self) {
        // wait (bounded) until the node is idle
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let o = Command::new("sinfo")
                .args(["-h", "-o", "%T"])
                .env("SLURM_CONF", &self.conf)
                .output();
            if let Ok(o) = &o {
                if String::from_utf8_lossy(&o.stdout).trim() == "idle" {
                    break;
                }
            }
            assert!(
                Instant::now() < deadline,
                "the test's Slurm cluster did not come up within 60 s (sinfo: {:?}):\n{}",
                o.map(|o| String::from_utf8_lossy(&o.stdout).into_owned()),
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// `crawler-sweep ARGS` in `dir` against this cluster, killed (and the test failed, with the
    /// daemons' logs) if it takes more than three minutes.
    fn sweep(&self, dir: &Path, args: &[&str]) -> Output {
        let mut child = Command::new(sweep_bin())
            .args(args)
            .current_dir(dir)
            .env("SLURM_CONF", &self.conf)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (mut out, mut err) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
        let reader = std::thread::spawn(move || {
            let mut b = Vec::new();
            std::io::Read::read_to_end(&mut out, &mut b).unwrap();
            b
        });
        let err_reader = std::thread::spawn(move || {
            let mut b = Vec::new();
            std::io::Read::read_to_end(&mut err, &mut b).unwrap();
            b
        });
        let deadline = Instant::now() + Duration::from_secs(180);
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if Instant::now() > deadline {
                let _ = child.kill();
                let _ = child.wait();
                panic!(
                    "crawler-sweep {args:?} did not finish within 180 s:\n{}\n{}",
                    String::from_utf8_lossy(&err_reader.join().unwrap()),
                    self.logs()
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        Output {
            status,
            stdout: reader.join().unwrap(),
            stderr: err_reader.join().unwrap(),
        }
    }

    fn wait_idle_queue(&self, job: &str) {
        let deadline = Instant::now() + Duration::from_secs(180);
        loop {
            let o = Command::new("squeue")
                .args(["-h", "-j", job])
                .env("SLURM_CONF", &self.conf)
                .output()
                .unwrap();
            if String::from_utf8_lossy(&o.stdout).trim().is_empty() {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "job {job} still queued after 180 s:\n{}",
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

const SIX: &str = r#"
[set]
numerics.cells = 32
numerics.settle = 1.5
numerics.t_end = 3.0

[[axes]]
key = "friction.eps"
values = [0.1, 1.0]

[[axes]]
key = "actuation.alpha"
values = [0.5, 1.0, 1.5]

[evaluate]
plant = true
models = ["paper", "improved"]
"#;

#[test]
fn a_slurm_sweep_gives_the_local_sweeps_parquet_bit_for_bit() {
    let cluster = Cluster::start();
    let work = tempfile::tempdir().unwrap();
    let w = work.path();
    let plan = write_plan(w, "six", SIX);
    let p = plan.to_str().unwrap();

    let local = sweep(
        w,
        &[
            p,
            "--out",
            "local.parquet",
            "--store",
            "local-store",
            "--no-figures",
        ],
    );
    assert!(local.status.success(), "{}", stderr(&local));

    a_waited_sweep_equals_the_local_one(&cluster, w, p);
    let plan2 = write_plan(
        w,
        "two",
        &SIX.replace("values = [0.5, 1.0, 1.5]", "values = [0.7, 1.3]"),
    );
    let p2 = plan2.to_str().unwrap();
    a_submitted_sweep_is_collected_as_the_local_one(&cluster, w, p2);
    a_rerun_submits_nothing(&cluster, w, p2);
    drop(cluster);
}

/// `--wait` on the plan `p` in `w`: a job array of three tasks of two points, waited for and
/// collected, equal to the local sweep's `local.parquet`.
fn a_waited_sweep_equals_the_local_one(cluster: &Cluster, w: &Path, p: &str) {
    // --wait: a job array of three tasks of two points, waited for and collected
    let o = cluster.sweep(
        w,
        &[
            p,
            "--executor",
            "slurm",
            "--wait",
            "--chunk",
            "2",
            "--poll",
            "0.2",
            "--out",
            "slurm.parquet",
            "--store",
            "slurm-store",
            "--slurm-dir",
            "slurm",
            "--no-figures",
        ],
    );
    assert!(o.status.success(), "{}\n{}", stderr(&o), cluster.logs());
    assert!(
        stderr(&o).contains("3 array tasks of up to 2 points"),
        "{}",
        stderr(&o)
    );
    let sub = w.join("slurm/sub-000");
    for t in 0..3 {
        let lines = std::fs::read_to_string(sub.join(format!("task-{t}.jsonl"))).unwrap();
        assert_eq!(lines.lines().count(), 2, "task {t} wrote its chunk");
    }
    assert_same_results(&w.join("local.parquet"), &w.join("slurm.parquet"));
}

/// Without `--wait`, the plan `p2` (four points) in `w`: submitted, left to finish, then
/// `collect` merges the task files into `two.parquet`, equal to a local sweep of the same plan.
fn a_submitted_sweep_is_collected_as_the_local_one(cluster: &Cluster, w: &Path, p2: &str) {
    // without --wait: submit, let it finish, then `collect` merges the task files
    let o = cluster.sweep(
        w,
        &[
            p2,
            "--executor",
            "slurm",
            "--store",
            "slurm-store",
            "--slurm-dir",
            "slurm2",
            "--out",
            "two.parquet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let job = std::fs::read_to_string(w.join("slurm2/sub-000/job_id")).unwrap();
    assert!(!w.join("two.parquet").exists());
    cluster.wait_idle_queue(job.trim());
    let o = cluster.sweep(
        w,
        &[
            "collect",
            p2,
            "--store",
            "slurm-store",
            "--slurm-dir",
            "slurm2",
            "--out",
            "two.parquet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("4 records added"), "{}", stderr(&o));
    let o = sweep(
        w,
        &[p2, "--out", "two-local.parquet", "--store", "two-local"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_same_results(&w.join("two-local.parquet"), &w.join("two.parquet"));
}

/// A rerun of the plan `p2` in `w` finds every point stored and submits nothing.
fn a_rerun_submits_nothing(cluster: &Cluster, w: &Path, p2: &str) {
    // a rerun finds every point stored and submits nothing
    let o = cluster.sweep(
        w,
        &[
            p2,
            "--executor",
            "slurm",
            "--store",
            "slurm-store",
            "--slurm-dir",
            "slurm2",
            "--out",
            "two.parquet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("4 points, 4 stored, 0 to run"),
        "{}",
        stderr(&o)
    );
    assert!(!w.join("slurm2/sub-001").exists(), "nothing submitted");
}
