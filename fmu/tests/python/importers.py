"""Drives the plant's FMUs with importers we did not write (FMPy, ecos) for fmu/tests/importers/.

Each command prints one JSON object on stdout; floats are written with repr() (shortest
round-trip form), so the Rust side compares bits. Run with the project's venv:

    .venv/bin/python fmu/tests/python/importers.py COMMAND FMU [options]

Commands:
  validate FMU                 fmpy's validate_fmu: {"problems": [...]}
  simulate FMU                 fmpy.simulate_fmu over the default experiment in steps of H:
                               final outputs, the state digest of u and v
  default FMU                  fmpy.simulate_fmu(FMU) with FMPy's default output interval:
                               rows, the interval, the last time, H and the stop time
  state FMU T1 T2              state round trip: get + serialize at T1, go on to T2, restore
                               (same instance, and a fresh one from the bytes), replay to T2
  two FMU                      two instances with different parameters, one stepped from a
                               second thread, against each run alone
  ecos FMU STEPS               ecos simulates the FMI 2.0 FMU for STEPS steps of H
  libcosim FMU STEP_NS STEPS [NAME=VALUE ...]
                               libcosim (libcosimpy) steps the FMI 2.0 FMU STEPS times on its
                               integer clock, STEP_NS nanoseconds a step, after setting the
                               parameters NAME (Integer or Real) to VALUE: final outputs, the
                               state digest; or {"ok": false, "error": ...} if a step failed
  ssp-ecos SSP STEP_NS STEPS [SET]
                               ecos loads the SSP file (plant and controller FMUs) with its
                               parameter set SET ("crawler"; "-" for none) and runs STEPS steps
                               of STEP_NS / 1e9 s: the plant's final outputs, state digest and
                               wave inputs
  ssp-libcosim SSP STEP_NS STEPS
                               the same in libcosim, on its nanosecond clock
"""

import json
import os
import struct
import sys
import threading
import zlib

OUTPUTS = [
    "velocity",
    "power",
    "mileage",
    "max_stress",
    "max_strain",
    "stuck_fraction",
    "mean_friction_selection",
    "steady_periods",
    "episode_rate",
    "mean_speed",
    "input_power",
    "tail_displacement",
    "mean_displacement",
]


def variables(md):
    return {v.name: v for v in md.modelVariables}


def read_fields(fmu, md):
    """u, v and the internal step count of an FMI 2 or 3 instance."""
    vs = variables(md)
    if md.fmiVersion.startswith("3"):
        n = int(fmu.getUInt64([vs["cells"].valueReference])[0])
        u = list(fmu.getFloat64([vs["u"].valueReference], nValues=n))
        v = list(fmu.getFloat64([vs["v"].valueReference], nValues=n))
        substeps = int(fmu.getUInt64([vs["substeps"].valueReference])[0])
        t = fmu.getFloat64([vs["time"].valueReference])[0] if False else None
    else:
        n = int(fmu.getInteger([vs["cells"].valueReference])[0])
        u = list(fmu.getReal([vs[f"u[{i + 1}]"].valueReference for i in range(n)]))
        v = list(fmu.getReal([vs[f"v[{i + 1}]"].valueReference for i in range(n)]))
        substeps = int(fmu.getInteger([vs["substeps"].valueReference])[0])
        t = None
    return u, v, substeps, t


def digest(u, v, internal_steps):
    """The plant's state digest: CRC-32 of the internal step count and the bits of u and v."""
    data = struct.pack("<Q", internal_steps)
    data += b"".join(struct.pack("<d", x) for x in u + v)
    return "%08x" % (zlib.crc32(data) & 0xFFFFFFFF)


def get_reals(fmu, md, names):
    vs = variables(md)
    refs = [vs[n].valueReference for n in names]
    if md.fmiVersion.startswith("3"):
        return list(fmu.getFloat64(refs))
    return list(fmu.getReal(refs))


def instantiate(path, name="plant"):
    from fmpy import extract, read_model_description, instantiate_fmu

    unzipdir = extract(path)
    md = read_model_description(unzipdir)
    fmu = instantiate_fmu(unzipdir, md, fmi_type="CoSimulation", visible=False, debug_logging=False)
    return fmu, md, unzipdir


def initialize(fmu, md, start_values=None):
    start_values = start_values or {}
    vs = variables(md)
    three = md.fmiVersion.startswith("3")
    if not three:
        fmu.setupExperiment(startTime=0.0)
    for name, value in start_values.items():
        ref = [vs[name].valueReference]
        if three:
            fmu.setFloat64(ref, [value])
        else:
            fmu.setReal(ref, [value])
    if three:
        fmu.enterInitializationMode(startTime=0.0)
    else:
        fmu.enterInitializationMode()
    fmu.exitInitializationMode()


def step_size(md):
    if md.fmiVersion.startswith("3"):
        return float(md.coSimulation.fixedInternalStepSize)
    return float(md.defaultExperiment.stepSize)


def do_steps(fmu, md, first, count):
    """Steps `count` times from step `first`, with FMPy's own time arithmetic (t = n h)."""
    h = step_size(md)
    for n in range(first, first + count):
        t = n * h
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=(n + 1) * h - t)


def snapshot(fmu, md, macro_steps):
    u, v, substeps, _ = read_fields(fmu, md)
    values = get_reals(fmu, md, OUTPUTS)
    return {
        "digest": digest(u, v, substeps * macro_steps),
        "outputs": dict(zip(OUTPUTS, values)),
    }


def cmd_validate(path):
    from fmpy.validation import validate_fmu

    print(json.dumps({"problems": validate_fmu(path)}))


def cmd_simulate(path):
    from fmpy import read_model_description, simulate_fmu, extract

    unzipdir = extract(path)
    md = read_model_description(unzipdir)
    h = step_size(md)
    stop = float(md.defaultExperiment.stopTime)
    fmu, _, _ = instantiate(path)
    result = simulate_fmu(
        unzipdir,
        model_description=md,
        fmu_instance=fmu,
        stop_time=stop,
        output_interval=h,
        output=["mean_displacement", "tail_displacement", "velocity"],
        terminate=False,
    )
    steps = len(result) - 1
    out = snapshot(fmu, md, steps)
    out.update(
        {
            "steps": steps,
            "final_time": float(result["time"][-1]),
            "h": h,
            "rows": len(result),
        }
    )
    fmu.terminate()
    fmu.freeInstance()
    print(json.dumps(out))


def cmd_default(path):
    from fmpy import read_model_description, simulate_fmu

    md = read_model_description(path)
    result = simulate_fmu(path)
    print(
        json.dumps(
            {
                "rows": len(result),
                "interval": float(result["time"][1] - result["time"][0]),
                "final_time": float(result["time"][-1]),
                "h": step_size(md),
                "stop_time": float(md.defaultExperiment.stopTime),
            }
        )
    )


def cmd_state(path, t1, t2):
    fmu, md, unzipdir = instantiate(path, "first")
    h = step_size(md)
    n1, n2 = round(t1 / h), round(t2 / h)
    initialize(fmu, md)
    do_steps(fmu, md, 0, n1)
    state = fmu.getFMUState()
    blob = bytes(fmu.serializeFMUState(state))
    do_steps(fmu, md, n1, n2 - n1)
    straight = snapshot(fmu, md, n2)
    fmu.setFMUState(state)
    back = snapshot(fmu, md, n1)
    do_steps(fmu, md, n1, n2 - n1)
    replay = snapshot(fmu, md, n2)
    fmu.freeFMUState(state)
    fmu.terminate()
    fmu.freeInstance()

    from fmpy import instantiate_fmu

    fresh = instantiate_fmu(unzipdir, md, fmi_type="CoSimulation", visible=False)
    initialize(fresh, md)
    restored = fresh.deserializeFMUState(blob)
    fresh.setFMUState(restored)
    fresh_back = snapshot(fresh, md, n1)
    do_steps(fresh, md, n1, n2 - n1)
    fresh_replay = snapshot(fresh, md, n2)
    fresh.freeFMUState(restored)
    fresh.terminate()
    fresh.freeInstance()
    print(
        json.dumps(
            {
                "bytes": len(blob),
                "straight": straight,
                "restored_at_t1": back,
                "replay": replay,
                "fresh_at_t1": fresh_back,
                "fresh_replay": fresh_replay,
            }
        )
    )


def cmd_two(path):
    """Instance a (paper) and b (eps = 1, f0 = 0.2: stick-slip) side by side; b is stepped from
    another thread while a steps in this one. Each is compared with a run of its own."""
    fmu_a, md, _ = instantiate(path, "a")
    fmu_b, _, _ = instantiate(path, "b")
    steps = 400
    b_values = {"eps": 1.0, "wave_f0": 0.2}
    initialize(fmu_a, md)
    initialize(fmu_b, md, b_values)
    worker = threading.Thread(target=do_steps, args=(fmu_b, md, 0, steps))
    worker.start()
    do_steps(fmu_a, md, 0, steps)
    worker.join()
    together = {"a": snapshot(fmu_a, md, steps), "b": snapshot(fmu_b, md, steps)}
    for f in (fmu_a, fmu_b):
        f.terminate()
        f.freeInstance()
    alone = {}
    for name, values in (("a", {}), ("b", b_values)):
        f, _, _ = instantiate(path, name)
        initialize(f, md, values)
        do_steps(f, md, 0, steps)
        alone[name] = snapshot(f, md, steps)
        f.terminate()
        f.freeInstance()
    print(json.dumps({"together": together, "alone": alone}))


def cmd_ecos(path, steps):
    from ecospy import EcosSimulation, EcosSimulationStructure
    from fmpy import read_model_description

    md = read_model_description(path)
    h = step_size(md)
    structure = EcosSimulationStructure()
    structure.add_model("plant", path)
    with EcosSimulation(structure=structure, step_size=h) as sim:
        if sim.init() is False:
            raise SystemExit("ecos could not initialise the FMU")
        t = sim.step(steps)
        n = sim.get_integer("plant::cells")
        u = [sim.get_real(f"plant::u[{i + 1}]") for i in range(n)]
        v = [sim.get_real(f"plant::v[{i + 1}]") for i in range(n)]
        substeps = sim.get_integer("plant::substeps")
        outputs = {name: sim.get_real(f"plant::{name}") for name in OUTPUTS}
        sim.terminate()
    print(
        json.dumps(
            {
                "time": t,
                "h": h,
                "digest": digest(u, v, substeps * steps),
                "outputs": outputs,
            }
        )
    )


def cmd_libcosim(path, step_ns, steps, assignments):
    # libcosim and its FMI Library write their log to file descriptor 1: send it to stderr while
    # they run, so that stdout carries only the JSON answer
    stdout = os.dup(1)
    os.dup2(2, 1)
    try:
        answer = libcosim_run(path, step_ns, steps, assignments)
    finally:
        sys.stdout.flush()
        os.dup2(stdout, 1)
        os.close(stdout)
    print(json.dumps(answer))


def libcosim_run(path, step_ns, steps, assignments):
    from fmpy import read_model_description
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    from libcosimpy._internal import get_last_error_message

    log_output_level(CosimLogLevel.ERROR)
    md = read_model_description(path)
    vs = variables(md)
    execution = CosimExecution.from_step_size(step_size=step_ns)
    slave = CosimLocalSlave(fmu_path=path, instance_name="plant")
    index = execution.add_local_slave(local_slave=slave)
    for assignment in assignments:
        name, value = assignment.split("=", 1)
        v = vs[name]
        if v.type == "Integer":
            ok = execution.integer_initial_value(index, v.valueReference, int(value))
        elif v.type == "Real":
            ok = execution.real_initial_value(index, v.valueReference, float(value))
        else:
            raise SystemExit(f"{name} is a {v.type}: only Integer and Real parameters are set here")
        if not ok:
            raise SystemExit(f"libcosim refused {name} = {value}: {get_last_error_message()}")
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer=observer)
    if not execution.step(step_count=steps):
        return {"ok": False, "error": get_last_error_message()}
    time_ns = execution.status().current_time
    ref = lambda name: vs[name].valueReference  # noqa: E731
    n = observer.last_integer_values(index, [ref("cells")])[0]
    u = observer.last_real_values(index, [ref(f"u[{i + 1}]") for i in range(n)])
    v = observer.last_real_values(index, [ref(f"v[{i + 1}]") for i in range(n)])
    substeps, ticks = observer.last_integer_values(index, [ref("substeps"), ref("ticks_per_second")])
    h, dt = observer.last_real_values(index, [ref("communication_step"), ref("dt")])
    values = observer.last_real_values(index, [ref(name) for name in OUTPUTS])
    return {
        "ok": True,
        "time_ns": time_ns,
        "h": h,
        "dt": dt,
        "ticks_per_second": ticks,
        "digest": digest(list(u), list(v), substeps * steps),
        "outputs": dict(zip(OUTPUTS, values)),
    }


WAVE = ["wave_f0", "wave_k", "wave_omega", "wave_phase"]


def plant_description(ssp):
    """The plant FMU's model description, read from inside the SSP archive."""
    import tempfile
    import zipfile

    from fmpy import read_model_description

    with tempfile.TemporaryDirectory() as d:
        with zipfile.ZipFile(ssp) as z:
            z.extract("resources/crawler_physics.fmu", d)
        return read_model_description(os.path.join(d, "resources", "crawler_physics.fmu"))


def cmd_ssp_ecos(ssp, step_ns, steps, parameter_set):
    from ecospy import EcosSimulation

    with EcosSimulation(ssp_path=ssp, step_size=step_ns / 1e9) as sim:
        if sim.init(parameter_set=None if parameter_set == "-" else parameter_set) is False:
            raise SystemExit("ecos could not initialise the SSP system")
        t = sim.step(steps)
        n = sim.get_integer("plant::cells")
        u = [sim.get_real(f"plant::u[{i + 1}]") for i in range(n)]
        v = [sim.get_real(f"plant::v[{i + 1}]") for i in range(n)]
        substeps = sim.get_integer("plant::substeps")
        answer = {
            "time": t,
            "ticks_per_second": sim.get_integer("plant::ticks_per_second"),
            "h": sim.get_real("plant::communication_step"),
            "digest": digest(u, v, substeps * steps),
            "outputs": {name: sim.get_real(f"plant::{name}") for name in OUTPUTS},
            "wave": {name: sim.get_real(f"plant::{name}") for name in WAVE},
        }
        sim.terminate()
    print(json.dumps(answer))


def cmd_ssp_libcosim(ssp, step_ns, steps):
    stdout = os.dup(1)
    os.dup2(2, 1)
    try:
        answer = ssp_libcosim_run(ssp, step_ns, steps)
    finally:
        sys.stdout.flush()
        os.dup2(stdout, 1)
        os.close(stdout)
    print(json.dumps(answer))


def ssp_libcosim_run(ssp, step_ns, steps):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy._internal import get_last_error_message

    log_output_level(CosimLogLevel.ERROR)
    vs = variables(plant_description(ssp))
    # the step in nanoseconds: libcosim would truncate a step in seconds (docs/fmu.md)
    execution = CosimExecution.from_ssp_file(ssp_path=ssp, step_size=step_ns)
    index = execution.slave_index_from_instance_name("plant")
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer=observer)
    if not execution.step(step_count=steps):
        return {"ok": False, "error": get_last_error_message()}
    ref = lambda name: vs[name].valueReference  # noqa: E731
    n = observer.last_integer_values(index, [ref("cells")])[0]
    u = observer.last_real_values(index, [ref(f"u[{i + 1}]") for i in range(n)])
    v = observer.last_real_values(index, [ref(f"v[{i + 1}]") for i in range(n)])
    substeps, ticks = observer.last_integer_values(index, [ref("substeps"), ref("ticks_per_second")])
    (h,) = observer.last_real_values(index, [ref("communication_step")])
    return {
        "ok": True,
        "time_ns": execution.status().current_time,
        "ticks_per_second": ticks,
        "h": h,
        "digest": digest(list(u), list(v), substeps * steps),
        "outputs": dict(zip(OUTPUTS, observer.last_real_values(index, [ref(x) for x in OUTPUTS]))),
        "wave": dict(zip(WAVE, observer.last_real_values(index, [ref(x) for x in WAVE]))),
    }


def main(argv):
    if len(argv) < 3:
        raise SystemExit(__doc__)
    cmd, path = argv[1], argv[2]
    if cmd == "validate":
        cmd_validate(path)
    elif cmd == "simulate":
        cmd_simulate(path)
    elif cmd == "default":
        cmd_default(path)
    elif cmd == "state":
        cmd_state(path, float(argv[3]), float(argv[4]))
    elif cmd == "two":
        cmd_two(path)
    elif cmd == "ecos":
        cmd_ecos(path, int(argv[3]))
    elif cmd == "libcosim":
        cmd_libcosim(path, int(argv[3]), int(argv[4]), argv[5:])
    elif cmd == "ssp-ecos":
        cmd_ssp_ecos(path, int(argv[3]), int(argv[4]), argv[5] if len(argv) > 5 else "crawler")
    elif cmd == "ssp-libcosim":
        cmd_ssp_libcosim(path, int(argv[3]), int(argv[4]))
    else:
        raise SystemExit(f"unknown command {cmd!r}\n{__doc__}")


if __name__ == "__main__":
    main(sys.argv)
