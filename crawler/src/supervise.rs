//! Supervising the run's processes: each in its own process group, its log forwarded with a
//! prefix, its output collected; the first failure stops the others, Ctrl-C stops all in order.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Child, Command, ExitCode, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crawler_cli::Exit;

/// Forwards a child's stream line by line with a prefix, and signals the first line that
/// contains `needle` (if any).
fn forward(
    name: &'static str,
    stream: impl Read + Send + 'static,
    needle: Option<(&'static str, std::sync::mpsc::Sender<()>)>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let mut needle = needle;
        for line in BufReader::new(stream).lines().map_while(Result::ok) {
            eprintln!("[{name}] {line}");
            if needle.as_ref().is_some_and(|(n, _)| line.contains(n)) {
                if let Some((_, tx)) = needle.take() {
                    let _ = tx.send(());
                }
            }
        }
    })
}

fn collect(stream: impl Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut s = String::new();
        let _ = BufReader::new(stream).read_to_string(&mut s);
        s
    })
}

pub struct Proc {
    /// Its name in messages (`plant`, `controller`, `recorder`).
    pub name: &'static str,
    /// The process.
    pub child: Child,
    out: Option<std::thread::JoinHandle<String>>,
    err: Option<std::thread::JoinHandle<()>>,
}

pub fn spawn(
    name: &'static str,
    exe: &Path,
    args: &[String],
    needle: Option<(&'static str, std::sync::mpsc::Sender<()>)>,
) -> anyhow::Result<Proc> {
    let mut cmd = Command::new(exe);
    // Each process in its own process group: Ctrl-C in a terminal reaches the launcher alone,
    // which stops the run in order (plant, controller, recorder) and exits 130.
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        cmd.process_group(0);
    }
    let mut child = cmd
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| anyhow::anyhow!("cannot start {}: {e}", exe.display()))?;
    let out = child.stdout.take().map(collect);
    let err = child.stderr.take().map(|s| forward(name, s, needle));
    Ok(Proc {
        name,
        child,
        out,
        err,
    })
}

impl Proc {
    /// `Some(exit code)` once the process has ended (`Some(None)`: killed by a signal).
    pub fn ended(&mut self) -> Option<Option<i32>> {
        match self.child.try_wait() {
            Ok(Some(s)) => Some(s.code()),
            Ok(None) => None,
            Err(_) => Some(None),
        }
    }

    /// Waits up to `timeout`; on timeout sends SIGINT, then kills after a grace period.
    pub fn finish(&mut self, timeout: Duration) -> (Option<i32>, String) {
        let deadline = Instant::now() + timeout;
        let status = loop {
            match self.child.try_wait() {
                Ok(Some(s)) => break Some(s),
                Ok(None) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(50))
                }
                _ => break None,
            }
        };
        let status = status.or_else(|| {
            eprintln!("crawler: {} still running; asking it to stop", self.name);
            interrupt(&self.child);
            let grace = Instant::now() + Duration::from_secs(10);
            loop {
                match self.child.try_wait() {
                    Ok(Some(s)) => break Some(s),
                    Ok(None) if Instant::now() < grace => {
                        std::thread::sleep(Duration::from_millis(50))
                    }
                    _ => {
                        let _ = self.child.kill();
                        break self.child.wait().ok();
                    }
                }
            }
        });
        let out = self
            .out
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        if let Some(h) = self.err.take() {
            let _ = h.join();
        }
        (status.and_then(|s| s.code()), out)
    }
}

/// True if Ctrl-C reached the launcher, waiting briefly when a child ended interrupted (130): a
/// terminal's Ctrl-C reaches every process of the group at once, and a child may end before the
/// launcher's own handler has run. A child interrupted alone (another SIGINT to it) is a failure.
pub fn interrupted_with(flag: &AtomicBool, failed: Option<(&'static str, Option<i32>)>) -> bool {
    if flag.load(Ordering::SeqCst) {
        return true;
    }
    if !failed.is_some_and(|(_, code)| Exit::Interrupted.is(code)) {
        return false;
    }
    let until = Instant::now() + Duration::from_millis(500);
    while Instant::now() < until {
        std::thread::sleep(Duration::from_millis(10));
        if flag.load(Ordering::SeqCst) {
            return true;
        }
    }
    false
}

/// The name and exit code of the first process that ended with a failure, if any.
pub fn first_failure(procs: &mut [&mut Proc]) -> Option<(&'static str, Option<i32>)> {
    procs.iter_mut().find_map(|p| match p.ended() {
        Some(code) if !Exit::Finished.is(code) => Some((p.name, code)),
        _ => None,
    })
}

/// Stops every process after `failed` ended with a failure; the exit status of the launcher.
pub fn stop_all(failed: (&'static str, Option<i32>), procs: &mut [&mut Proc]) -> ExitCode {
    let (name, code) = failed;
    let what = if Exit::Interrupted.is(code) {
        "was interrupted"
    } else {
        "failed"
    };
    let code = code.map_or_else(|| "a signal".to_string(), |c| format!("exit code {c}"));
    eprintln!("crawler: the {name} {what} ({code}; its messages are above); stopping the others");
    for p in procs.iter_mut() {
        if p.ended().is_none() {
            interrupt(&p.child);
        }
    }
    for p in procs.iter_mut() {
        let _ = p.finish(Duration::from_secs(10));
    }
    Exit::Failure.into()
}

/// After Ctrl-C: asks every running process to stop (they finish cleanly: the plant writes its
/// checkpoint, the recorder closes its file), waits for them and prints what the plant said.
pub fn stop_interrupted(procs: &mut [&mut Proc]) -> ExitCode {
    eprintln!("crawler: interrupted; stopping the run");
    for p in procs.iter_mut() {
        if p.ended().is_none() {
            interrupt(&p.child);
        }
    }
    for p in procs.iter_mut() {
        let (_, out) = p.finish(Duration::from_secs(30));
        if p.name == "plant" && !out.trim().is_empty() {
            println!("{}", out.trim_end());
        }
    }
    Exit::Interrupted.into()
}

pub fn interrupt(child: &Child) {
    // SIGINT lets the process finish cleanly (the bridge closes its recording properly).
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn a_child_interrupted_with_the_launcher_is_a_ctrl_c_and_alone_a_failure() {
        let flag = AtomicBool::new(false);
        let interrupted = Some(("controller", Some(130)));
        // nothing ended, no Ctrl-C; a child failed on its own
        assert!(!interrupted_with(&flag, None));
        assert!(!interrupted_with(&flag, Some(("plant", Some(1)))));
        assert!(!interrupted_with(&flag, Some(("plant", None))));
        // a child ended with 130 and no Ctrl-C reached the launcher: a failure, after the wait
        let t0 = Instant::now();
        assert!(!interrupted_with(&flag, interrupted));
        assert!(t0.elapsed() >= Duration::from_millis(500));
        // the launcher's handler runs a little after the child ended
        let late = Arc::new(AtomicBool::new(false));
        let setter = {
            let late = late.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(50));
                late.store(true, Ordering::SeqCst);
            })
        };
        assert!(interrupted_with(&late, interrupted));
        setter.join().unwrap();
        // Ctrl-C reached the launcher: interrupted whatever the children did
        flag.store(true, Ordering::SeqCst);
        assert!(interrupted_with(&flag, None));
        assert!(interrupted_with(&flag, Some(("plant", Some(1)))));
    }
}
