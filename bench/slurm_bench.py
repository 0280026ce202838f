#!/usr/bin/env python3
"""Slurm executor: overhead per point with chunking, against the local executor, in one run.

Builds crawler-sweep (release) first, installs Slurm if needed (scripts/setup-slurm.sh; root),
starts a private single-node cluster in a temporary folder (its own munge key and socket, free
loopback ports, the same settings as the test in sweep/tests/slurm.rs), runs one plan of short
plant points (about 0.1 s each) locally with all cores and as a Slurm job array with several
chunk sizes (each into a fresh store, waiting for the job), stops the cluster, and prints

    overhead per point = (Slurm wall time - local wall time) / points

as a share of the plant time per point (the mean of the points' own wall times).

    .venv/bin/python bench/slurm_bench.py [--points 600] [--chunks 5,25,100]
"""
import argparse
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time

import pyarrow.parquet as pq

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "target", "release", "crawler-sweep")

PLAN = """name = "slurmbench"
scenario = "{scenario}"
[set]
numerics.cells = {cells}
numerics.settle = 1.0
numerics.t_end = 2.0
actuation.k = 12.566370614359172
friction.eps = 0.5
[[axes]]
key = "actuation.alpha"
linspace = {{ start = 0.3, stop = 1.8, num = {points} }}
[evaluate]
plant = true
convergence = false
models = ["paper"]
"""


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def start_cluster(d):
    procs = []
    key = os.path.join(d, "munge.key")
    with open(key, "wb") as f:
        f.write(os.urandom(1024))
    os.chmod(key, 0o400)
    sock = os.path.join(d, "munge.socket")
    procs.append(subprocess.Popen(["munged", "--foreground", "--force", f"--socket={sock}", f"--key-file={key}",
                                   f"--log-file={d}/munged.log", f"--pid-file={d}/munged.pid",
                                   f"--seed-file={d}/munged.seed"]))
    for _ in range(100):
        if os.path.exists(sock):
            break
        time.sleep(0.05)
    host = subprocess.run(["hostname", "-s"], capture_output=True, text=True).stdout.strip()
    for sub in ("state", "spool"):
        os.makedirs(os.path.join(d, sub))
    conf = os.path.join(d, "slurm.conf")
    with open(conf, "w") as f:
        f.write(f"""ClusterName=crawlerbench
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={free_port()}
SlurmdPort={free_port()}
AuthType=auth/munge
AuthInfo=socket={sock}
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/slurmd.pid
SlurmctldLogFile={d}/slurmctld.log
SlurmdLogFile={d}/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
DefMemPerCPU=100
SchedulerType=sched/builtin
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
NodeName={host} NodeAddr=127.0.0.1 CPUs={os.cpu_count()} RealMemory=1000 State=UNKNOWN
PartitionName=bench Nodes={host} Default=YES MaxTime=INFINITE State=UP
""")
    env = dict(os.environ, SLURM_CONF=conf)
    procs.append(subprocess.Popen(["slurmctld", "-D", "-f", conf], env=env))
    procs.append(subprocess.Popen(["slurmd", "-D", "-f", conf], env=env))
    for _ in range(300):
        out = subprocess.run(["sinfo", "-h", "-o", "%T"], env=env, capture_output=True, text=True).stdout.strip()
        if out == "idle":
            return procs, env
        time.sleep(0.2)
    stop(procs)
    sys.exit("the benchmark's Slurm cluster did not come up within 60 s")


def stop(procs):
    for p in reversed(procs):
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def timed(args, cwd, env=None):
    t = time.perf_counter()
    subprocess.run([BIN, *args, "--no-progress", "--no-figures"], cwd=cwd, env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=600)
    ap.add_argument("--cells", type=int, default=1024)
    ap.add_argument("--chunks", default="5,25,100")
    a = ap.parse_args()
    print("building crawler-sweep (cargo build --release -p crawler-sweep) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-p", "crawler-sweep"], cwd=ROOT, check=True)
    subprocess.run(["bash", os.path.join(ROOT, "scripts", "setup-slurm.sh")], check=True)
    with tempfile.TemporaryDirectory(prefix="crawler-slurm-bench") as d:
        plan = os.path.join(d, "plan.toml")
        with open(plan, "w") as f:
            f.write(PLAN.format(scenario=os.path.join(ROOT, "scenarios", "paper.toml"), cells=a.cells,
                                points=a.points))
        cluster_dir = os.path.join(d, "cluster")
        os.makedirs(cluster_dir)
        procs, env = start_cluster(cluster_dir)
        try:
            out = os.path.join(d, "local.parquet")
            t_local = timed([plan, "--store", os.path.join(d, "s-local"), "--out", out], d)
            per_point = sum(pq.read_table(out, columns=["wall_time"]).column(0).to_pylist()) / a.points
            rows = []
            for c in [int(x) for x in a.chunks.split(",")]:
                t = timed([plan, "--executor", "slurm", "--wait", "--poll", "0.2", "--chunk", str(c),
                           "--store", os.path.join(d, f"s-{c}"), "--slurm-dir", os.path.join(d, f"slurm-{c}"),
                           "--out", os.path.join(d, f"slurm-{c}.parquet")], d, env)
                rows.append((c, t))
        finally:
            stop(procs)
    cores = os.cpu_count()
    print(f"{a.points} points of {per_point:.3f} s plant time each (N = {a.cells}, k = 4 pi, t_end = 2 s); "
          f"a single-node cluster with {cores} CPUs against the local executor with {cores} workers")
    print("| executor | chunk | array tasks | wall time | overhead per point | share of plant time |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    print(f"| local | | | {t_local:.2f} s | | |")
    for c, t in rows:
        ov = (t - t_local) / a.points
        print(f"| slurm | {c} | {-(-a.points // c)} | {t:.2f} s | {ov * 1000:.1f} ms | **{100 * ov / per_point:.1f} %** |")


if __name__ == "__main__":
    main()
