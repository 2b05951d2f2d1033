#!/usr/bin/env python3
"""Check the cable-servo FMU with FMPy: validation, a closed loop against the native run,
load/unload cycles, independent instances and bad input.

The closed loop is the project's PID (src/closed_loop/controller.rs) written again in
Python, run at the scenario's sample rate with one FMU step per control period, against
the FMU's plant; its pointing error over the metrics window must match the native
`cable-servo run` (mode none) summary within --tolerance (relative, RMS and peak).

    python3 -m pip install fmpy
    cargo build --release
    target/release/cable-servo export-fmu eots_tracking --out drive.fmu
    target/release/cable-servo run eots_tracking --set 'closed_loop.modes=["none"]' --out results/native_none
    python3 scripts/fmu_check.py --fmu drive.fmu --summary results/native_none/summary.json

Exit status 0 when every check passes, 1 otherwise, 2 when FMPy is missing.
"""

import argparse
import ctypes
import json
import resource
import shutil
import sys
import time
import tomllib
from pathlib import Path

try:
    import fmpy
    from fmpy import calloc, extract, free, read_model_description
    from fmpy.fmi2 import (
        FMU2Slave,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
    )
    from fmpy.validation import validate_fmu
except ImportError:
    print("skipped: FMPy is not installed (python3 -m pip install fmpy)")
    sys.exit(2)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fmu_example import closed_loop  # noqa: E402  (the example of docs/fmu.md is what runs here)


class Log:
    """FMU log messages, kept per instance."""

    def __init__(self):
        self.lines = []
        self.callbacks = fmi2CallbackFunctions()
        # The FMU passes each message as a format string without conversions.
        self._logger = fmi2CallbackLoggerTYPE(self._log)
        self._alloc = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._free = fmi2CallbackFreeMemoryTYPE(free)
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = self._alloc
        self.callbacks.freeMemory = self._free

    def _log(self, env, name, status, category, message):
        self.lines.append((status, category.decode(), message.decode()))

    def last(self):
        return self.lines[-1][2] if self.lines else "(no message)"


class Plant:
    """One FMU instance, its status codes returned rather than raised (the bad-input
    checks want them), messages kept."""

    def __init__(self, md, unzipdir, name="plant", logging_on=False):
        self.log = Log()
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=unzipdir,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.fmu.instantiate(callbacks=self.log.callbacks, loggingOn=logging_on)
        dll = self.fmu.dll
        self.c = self.fmu.component
        self._step = dll.fmi2DoStep
        self._step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        self._step.restype = ctypes.c_int
        self._get = dll.fmi2GetReal
        self._get.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p]
        self._get.restype = ctypes.c_int
        self._set = dll.fmi2SetReal
        self._set.argtypes = self._get.argtypes
        self._set.restype = ctypes.c_int
        self._init = dll.fmi2ExitInitializationMode
        self._init.argtypes = [ctypes.c_void_p]
        self._init.restype = ctypes.c_int

    def status_init(self, start=0.0, stop=None, params=None):
        """Setup and initialisation; returns the status of fmi2ExitInitializationMode."""
        self.fmu.setupExperiment(startTime=start, stopTime=stop)
        self.fmu.enterInitializationMode()
        for name, value in (params or {}).items():
            self.fmu.setReal([self.vr[name]], [value])
        return self._init(self.c)

    def reader(self, names):
        vrs = (ctypes.c_uint * len(names))(*[self.vr[n] for n in names])
        out = (ctypes.c_double * len(names))()
        n = len(names)

        def read():
            s = self._get(self.c, vrs, n, out)
            if s > 1:
                raise RuntimeError(f"fmi2GetReal status {s}: {self.log.last()}")
            return out

        return read

    def writer(self, name):
        vr = (ctypes.c_uint * 1)(self.vr[name])
        val = (ctypes.c_double * 1)()

        def write(x):
            val[0] = x
            s = self._set(self.c, vr, 1, val)
            if s > 1:
                raise RuntimeError(f"fmi2SetReal status {s}: {self.log.last()}")

        return write

    def step(self, t, h):
        return self._step(self.c, t, h, 1)

    def free(self):
        self.fmu.freeInstance()  # also unloads the library


def plain(x, drop=None):
    """A scenario section with unset (null) keys and the key `drop` left out, for
    comparing the packed TOML with the summary's JSON."""
    if isinstance(x, dict):
        return {k: plain(v) for k, v in x.items() if v is not None and k != drop}
    if isinstance(x, list):
        return [plain(v) for v in x]
    return x


def rss_mb():
    """Resident set size now, MB (from /proc; the peak from getrusage elsewhere)."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        return pages * resource.getpagesize() / 2**20
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def short_run(md, unzipdir, name="plant"):
    """An initialised instance at t = 0."""
    plant = Plant(md, unzipdir, name)
    if plant.status_init() != 0:
        raise RuntimeError(plant.log.last())
    return plant


def check_cycles(md, unzipdir, cycles):
    """Load, run, unload `cycles` times; returns the RSS growth after the first cycles, MB."""
    h = 1e-4
    growth_from = None
    for i in range(cycles):
        plant = short_run(md, unzipdir, name=f"cycle{i}")
        cmd = plant.writer("motor_current_command_a") if "motor_current_command_a" in plant.vr else plant.writer("motor_voltage_command_v")
        cmd(0.5)
        for k in range(50):
            if plant.step(k * h, h) != 0:
                raise RuntimeError(plant.log.last())
        plant.fmu.terminate()
        plant.free()
        if i == 4:
            growth_from = rss_mb()
    return rss_mb() - growth_from


def check_two_instances(md, unzipdir):
    """Two instances stepped in turn give exactly what each gives alone."""
    h = 1e-4
    names = ["motor_angle_rad", "output_angle_rad", "tension_upper_n", "transmitted_torque_nm"]
    cmd_name = "motor_current_command_a" if any(v.name == "motor_current_command_a" for v in md.modelVariables) else "motor_voltage_command_v"

    def run(plant, u, steps):
        cmd = plant.writer(cmd_name)
        read = plant.reader(names)
        cmd(u)
        out = []
        for k in range(steps):
            if plant.step(k * h, h) != 0:
                raise RuntimeError(plant.log.last())
            out.append(tuple(read()))
        return out

    alone_a = short_run(md, unzipdir, name="alone_a")
    ref_a = run(alone_a, 2.0, 300)
    alone_a.fmu.terminate()
    alone_a.free()
    alone_b = short_run(md, unzipdir, name="alone_b")
    ref_b = run(alone_b, -1.0, 300)
    alone_b.fmu.terminate()
    alone_b.free()

    a = short_run(md, unzipdir, name="a")
    b = short_run(md, unzipdir, name="b")
    ca, cb = a.writer(cmd_name), b.writer(cmd_name)
    ra, rb = a.reader(names), b.reader(names)
    ca(2.0)
    cb(-1.0)
    got_a, got_b = [], []
    for k in range(300):
        if a.step(k * h, h) != 0 or b.step(k * h, h) != 0:
            raise RuntimeError(a.log.last() + " / " + b.log.last())
        got_a.append(tuple(ra()))
        got_b.append(tuple(rb()))
    a.fmu.terminate()
    b.fmu.terminate()
    a.free()
    b.free()
    return got_a == ref_a and got_b == ref_b and ref_a != ref_b


def check_bad_input(md, unzipdir):
    """Each bad call returns an error status with a message; the process goes on."""
    problems = []
    # A negative preload: refused at fmi2ExitInitializationMode, naming the parameter.
    p = Plant(md, unzipdir, "bad_preload")
    s = p.status_init(params={"drive.preload_n": -5.0})
    if s != 3 or "drive.preload_n" not in p.log.last():
        problems.append(f"negative preload: status {s}, message {p.log.last()!r}")
    p.free()
    # Zero and negative step sizes.
    p = short_run(md, unzipdir, name="bad_step")
    for h in (0.0, -1e-4):
        s = p.step(0.0, h)
        if s != 3 or "step size" not in p.log.last():
            problems.append(f"step size {h}: status {s}, message {p.log.last()!r}")
    # The instance is still usable afterwards.
    if p.step(0.0, 1e-4) != 0:
        problems.append(f"a good step after bad ones failed: {p.log.last()}")
    p.fmu.terminate()
    p.free()
    # Out of order: a step before initialisation.
    p = Plant(md, unzipdir, "out_of_order")
    s = p.step(0.0, 1e-4)
    if s != 3 or "not allowed" not in p.log.last():
        problems.append(f"step before initialisation: status {s}, message {p.log.last()!r}")
    p.free()
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmu", required=True, help="FMU written by cable-servo export-fmu")
    ap.add_argument("--summary", required=True, help="summary.json of the native run (mode none)")
    ap.add_argument("--tolerance", type=float, default=0.01, help="relative tolerance on RMS and peak (0.01)")
    ap.add_argument("--cycles", type=int, default=100, help="load/run/unload cycles (100)")
    ap.add_argument("--max-growth-mb", type=float, default=16.0, help="allowed memory growth over the cycles, MB")
    args = ap.parse_args()

    failures = []
    problems = validate_fmu(args.fmu)
    print(f"FMPy {fmpy.__version__} validate_fmu: {len(problems)} problem(s)")
    for p in problems:
        print("  ", p)
    if problems:
        failures.append("validation")

    with open(args.summary) as f:
        summary = json.load(f)
    native = next((m for m in summary["modes"] if m["name"] == "none"), None)
    if native is None:
        raise SystemExit("fmu_check: the summary holds no mode none")
    md = read_model_description(args.fmu)
    unzipdir = extract(args.fmu)
    try:
        packed = tomllib.loads(Path(unzipdir, "resources", "scenario.toml").read_text())
        # The modes list may differ (the native run may be limited to mode none).
        same = all(
            plain(packed.get(k), drop="modes") == plain(summary["scenario"].get(k), drop="modes")
            for k in ("drive", "load", "closed_loop", "effects")
        )
        print(f"scenario packed in the FMU equals the native run's (drive, load, closed loop, effects): {'ok' if same else 'FAIL'}")
        if not same:
            failures.append("scenario")
        log = Log()
        wall = time.perf_counter()
        try:
            rms, peak, count = closed_loop(args.fmu, callbacks=log.callbacks)
        except Exception as e:  # FMPy raises on a failed call; the FMU logged why
            print(f"closed loop FAILED: {e}: {log.last()}")
            return 1
        wall = time.perf_counter() - wall
        d_rms = abs(rms - native["rms_mrad"]) / native["rms_mrad"]
        d_peak = abs(peak - native["peak_mrad"]) / native["peak_mrad"]
        ok = d_rms <= args.tolerance and d_peak <= args.tolerance
        cl = packed["closed_loop"]
        print(
            f"closed loop (scripts/fmu_example.py), {cl['duration_s']} s at {cl['controller']['sample_rate_hz']} Hz, "
            f"{count} samples in the window, {wall:.1f} s wall:\n"
            f"   FMU + Python PID: rms {rms:.6f} mrad, peak {peak:.6f} mrad\n"
            f"   native run:       rms {native['rms_mrad']:.6f} mrad, peak {native['peak_mrad']:.6f} mrad\n"
            f"   relative difference: rms {d_rms:.2e}, peak {d_peak:.2e} (tolerance {args.tolerance}): {'ok' if ok else 'FAIL'}"
        )
        if not ok:
            failures.append("closed loop")

        independent = check_two_instances(md, unzipdir)
        print(f"two instances in one process independent: {'ok' if independent else 'FAIL'}")
        if not independent:
            failures.append("two instances")

        growth = check_cycles(md, unzipdir, args.cycles)
        ok = growth <= args.max_growth_mb
        print(f"{args.cycles} load/run/unload cycles: memory growth {growth:.1f} MB after the first five: {'ok' if ok else 'FAIL'}")
        if not ok:
            failures.append("cycles")

        bad = check_bad_input(md, unzipdir)
        print(f"bad input (negative preload, step size 0 and < 0, step before initialisation): {'ok' if not bad else 'FAIL'}")
        for b in bad:
            print("  ", b)
        if bad:
            failures.append("bad input")
    finally:
        shutil.rmtree(unzipdir, ignore_errors=True)

    if failures:
        print("FAILED: " + ", ".join(failures))
        return 1
    print("all FMU checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
