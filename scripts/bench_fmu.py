#!/usr/bin/env python3
"""Speed of the FMU (issue 25): the default scenario for DURATION s (default 60) through FMPy's
FMI 2.0 slave API with ERL-SMC written in Python as the master's controller, next to
`exoleg run` with the built-in controllers. A benchmark that prints figures, not a test.

    cargo build --release && cargo build --release -p exoleg-fmu
    python scripts/bench_fmu.py [DURATION_S]     (needs fmpy and the exoleg package)
"""

import math
import os
import subprocess
import sys
import tempfile
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.environ.get("EXOLEG_BIN", os.path.join(ROOT, "target", "release", "exoleg"))


def exoleg(*args):
    t0 = time.perf_counter()
    subprocess.run([BIN, *args], check=True, capture_output=True)
    return time.perf_counter() - t0


def fmu_run(fmu, duration_s):
    md = read_model_description(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    readings = [v.name for v in md.modelVariables if v.causality == "output" and v.valueReference < 100]
    rvr = [vr[n] for n in readings]
    idx = {n: i for i, n in enumerate(readings)}
    h = float(md.defaultExperiment.stepSize)
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier="exoleg", instanceName="bench")
    t0 = time.perf_counter()
    s.instantiate()
    s.setupExperiment(startTime=0.0, stopTime=duration_s)
    s.enterInitializationMode()
    s.exitInitializationMode()
    n1, n2, n3, tau, ks = s.getReal([vr[f"nominal.{k}"] for k in ("n1", "n2", "n3", "tau_s", "k_s")])
    k, delta, zeta = 100.0, 15.0, 10.0
    steps = round(duration_s / h)
    for j in range(steps):
        y = s.getReal(rvr)
        e = y[idx["ref_force_n"]] - y[idx["force_n"]]
        e_dot = y[idx["ref_force_rate_n_per_s"]] - y[idx["force_rate_n_per_s"]]
        sl = e_dot + delta * e
        accel = y[idx["ref_force_accel_n_per_s2"]] + delta * e_dot + k * sl + zeta * math.tanh(sl)
        u = tau / (n1 * ks) * (accel + n3 * y[idx["force_rate_n_per_s"]] + n2 * y[idx["piston_accel_m_s2"]] + n1 * y[idx["spool_m"]] / tau)
        s.setReal([vr["valve_command"]], [u])
        s.doStep(currentCommunicationPoint=j * h, communicationStepSize=h)
    err = s.getReal([vr["true_force_error_n"]])[0]
    s.terminate()
    s.freeInstance()
    return time.perf_counter() - t0, steps, err


def main():
    duration = float(sys.argv[1]) if len(sys.argv) > 1 else 60.0
    d = f"sim.duration_s={duration}"
    with tempfile.TemporaryDirectory() as tmp:
        fmu = os.path.join(tmp, "default.fmu")
        exoleg("fmu", "--out", fmu, "--set", d)
        wall, steps, err = fmu_run(fmu, duration)
        builtin = exoleg("run", "--quiet", "--out", os.path.join(tmp, "a"), "--set", d)
        erl = exoleg(
            "run", "--quiet", "--out", os.path.join(tmp, "b"), "--set", d,
            "--set", 'controller.kind="erl_smc"', "--set", "controller.sample_period_s=0.001",
        )
    print(f"default scenario (Rapier leg, dt 1 ms), {duration:g} s simulated:")
    print(f"  FMU through FMPy, ERL-SMC in Python   {wall:7.2f} s wall  ({wall / steps * 1e6:6.1f} us per 1 ms sample, "
          f"{duration / wall:5.1f}x real time; final force error {err:.2f} N)")
    print(f"  exoleg run, built-in ARBFNN-FDO-ZNN   {builtin:7.2f} s wall  ({duration / builtin:5.1f}x real time, writes outputs)")
    print(f"  exoleg run, built-in ERL-SMC at 1 kHz {erl:7.2f} s wall  ({duration / erl:5.1f}x real time, writes outputs)")


if __name__ == "__main__":
    main()
