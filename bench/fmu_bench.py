"""The FMU from FMPy against the plant in process, side by side in one run.

Usage: .venv/bin/python bench/fmu_bench.py [--repeat 3]

1. The paper scenario's 10 s run (N = 512, 10 097 communication steps of H = 0.99 ms):
   `crawler-plant simulate` (in process, no FMI) against `fmpy.simulate_fmu` stepping the FMI 2.0
   and the FMI 3.0 FMU from FMPy's Python loop (output_interval = H, recording three scalars per
   step), alternating, wall-clock medians of --repeat runs.
2. The cost of one `fmi3DoStep` of the packaged shared library (loaded with dlopen by the Rust
   harness fmu/examples/dostep_bench.rs) against `Slave::do_step` in process.

It builds first: `cargo build --release -p crawler-plant`, `scripts/build-fmu.sh` and the
harness (release).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))


def build(out):
    print("fmu_bench: building crawler-plant, the FMUs and the DoStep harness (release)...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant"], check=True, cwd=ROOT)
    subprocess.run(["bash", "scripts/build-fmu.sh", out], check=True, cwd=ROOT)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-fmu", "--example", "dostep_bench"],
                   check=True, cwd=ROOT)


def time_simulate():
    exe = os.path.join(TARGET, "release", "crawler-plant")
    t0 = time.perf_counter()
    out = subprocess.run([exe, "simulate", "--json"], check=True, capture_output=True, text=True).stdout
    return time.perf_counter() - t0, json.loads(out)


def time_fmpy(path):
    from fmpy import extract, read_model_description, simulate_fmu

    unzipdir = extract(path)
    md = read_model_description(unzipdir)
    h = float(md.defaultExperiment.stepSize)
    t0 = time.perf_counter()
    result = simulate_fmu(unzipdir, model_description=md, stop_time=float(md.defaultExperiment.stopTime),
                          output_interval=h, output=["mean_displacement", "tail_displacement", "velocity"])
    took = time.perf_counter() - t0
    return took, len(result) - 1, float(result["velocity"][-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as out:
        build(out)
        fmi2 = os.path.join(out, "crawler_physics.fmu")
        fmi3 = os.path.join(out, "crawler_plant_fmi3.fmu")
        times = {"simulate": [], "fmi2": [], "fmi3": []}
        for _ in range(a.repeat):
            t, report = time_simulate()
            times["simulate"].append(t)
            for key, path in (("fmi2", fmi2), ("fmi3", fmi3)):
                t, steps, v = time_fmpy(path)
                assert steps == report["macro_steps"] and v == report["velocity"], "not the same run"
                times[key].append(t)
        med = {k: statistics.median(v) for k, v in times.items()}
        steps = report["macro_steps"]
        print(f"paper scenario, N = {report['cells']}, {steps} steps of H, medians of {a.repeat} runs:")
        print("| run | wall time (s) | per step (us) | / in process |")
        print("| --- | ---: | ---: | ---: |")
        for key, label in (("simulate", "`crawler-plant simulate` (in process)"),
                           ("fmi2", "FMPy `simulate_fmu`, FMI 2.0 FMU"),
                           ("fmi3", "FMPy `simulate_fmu`, FMI 3.0 FMU")):
            print(f"| {label} | {med[key]:.3f} | {med[key] / steps * 1e6:.1f} | {med[key] / med['simulate']:.2f}x |")

        unpacked = os.path.join(out, "fmi3")
        with zipfile.ZipFile(fmi3) as z:
            z.extractall(unpacked)
        so = os.path.join(unpacked, "binaries", "x86_64-linux", "crawler_physics.so")
        harness = os.path.join(TARGET, "release", "examples", "dostep_bench")
        r = json.loads(subprocess.run([harness, so], check=True, capture_output=True, text=True).stdout)
        print()
        print(f"DoStep per macro step (N = {r['cells']}, {r['substeps']} internal steps each, median of "
              f"{r['rounds']} rounds of {r['macro_steps_per_round']} steps):")
        print("| call | us per macro step |")
        print("| --- | ---: |")
        print(f"| `fmi3DoStep` (packaged .so via dlopen) | {r['fmu_do_step_us']:.2f} |")
        print(f"| `Slave::do_step` (in process) | {r['slave_do_step_us']:.2f} |")
        print(f"| ratio | {r['ratio']:.3f} |")


if __name__ == "__main__":
    main()
