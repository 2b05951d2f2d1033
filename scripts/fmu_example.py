#!/usr/bin/env python3
"""The cable-servo FMU in a Python closed loop with FMPy: the project's PID (the loop of
`cable-servo run eots_tracking`, mode none) at the scenario's sample rate, the command
applied after the scenario's computation delay and held, one FMU step per control period
(two when the delay is a fraction of a period: the command changes inside it).

    python3 scripts/fmu_example.py drive.fmu

prints the RMS and peak pointing error over the metrics window. The controller's gains
and the reference come from the scenario packed in the FMU (resources/scenario.toml).
"""

import math
import shutil
import sys
import tomllib
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


class Pid:
    """The PID of src/closed_loop/controller.rs: derivative on the measurement through a
    first-order filter, integral frozen while the output is clipped into the limit."""

    def __init__(self, c, limit):
        t = 1.0 / c["sample_rate_hz"]
        self.kp = c["kp"]
        self.ki_t = c.get("ki", 0.0) * t
        self.kd_t = c.get("kd", 0.0) / t
        self.a = math.exp(-math.tau * c.get("derivative_filter_hz", 1000.0) * t)
        self.limit = limit
        self.integral = 0.0
        self.deriv = 0.0
        self.last_y = None

    def update(self, r, y, u_ff):
        e = r - y
        dy = y - (y if self.last_y is None else self.last_y)
        self.last_y = y
        self.deriv = self.a * self.deriv - (1.0 - self.a) * self.kd_t * dy
        candidate = self.integral + self.ki_t * e
        v = self.kp * e + candidate + self.deriv + u_ff
        u = min(max(v, -self.limit), self.limit)
        if not (u != v and e * (v - u) > 0.0):
            self.integral = candidate
        return u


class Delay:
    """The computation delay of src/closed_loop/controller.rs: with a delay of m + f
    periods (m whole), the period after sample k holds u_{k-m-1} for its first f and
    u_{k-m} for the rest (zeros before the first command)."""

    def __init__(self, delay_samples):
        whole = math.floor(max(delay_samples, 0.0))
        self.queue = [0.0] * (whole + 2)
        self.fraction = delay_samples - whole

    def push(self, u):
        self.queue = self.queue[1:] + [u]
        return self.queue[0], self.queue[1], self.fraction


def sine(ref):
    """The scenario's sine reference (src/signal.rs): value, rate, acceleration at t."""
    if ref.get("kind") != "sine":
        raise SystemExit(f"reference kind {ref.get('kind')!r}: this example implements the sine only")
    a, w = ref["amplitude_rad"], math.tau * ref["frequency_hz"]
    ph0, off = ref.get("phase_rad", 0.0), ref.get("offset_rad", 0.0)

    def at(t):
        ph = w * t + ph0
        return off + a * math.sin(ph), a * w * math.cos(ph), -a * w * w * math.sin(ph)

    return at


def closed_loop(fmu_path, scenario=None, duration_s=None, callbacks=None):
    """Runs the loop; returns (rms_mrad, peak_mrad, samples) of the pointing error
    `output angle - reference` over the scenario's metrics window."""
    md = read_model_description(fmu_path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipdir = extract(fmu_path)
    try:
        if scenario is None:
            scenario = tomllib.loads(Path(unzipdir, "resources", "scenario.toml").read_text())
        cl, c, drive = scenario["closed_loop"], scenario["closed_loop"]["controller"], scenario["drive"]
        if c.get("load_feedforward", False):
            raise SystemExit("load_feedforward = true is not implemented in this example")
        ic = drive["drum_radius_m"] / drive["pulley_radius_m"]
        motor = cl.get("motor", {})
        voltage = motor.get("amplifier", "current") == "voltage"
        limit = motor.get("voltage_limit_v" if voltage else "current_limit_a") or math.inf
        command = vr["motor_voltage_command_v" if voltage else "motor_current_command_a"]
        feedback = vr["output_encoder_rad" if c.get("feedback", "motor") == "output" else "motor_encoder_rad"]
        scale = ic if c.get("feedback", "motor") == "output" else 1.0
        ts = 1.0 / c["sample_rate_hz"]
        n = round((duration_s or cl["duration_s"]) * c["sample_rate_hz"])
        start = cl.get("metrics_start_s", 2.0)
        ref = sine(cl["reference"])
        vff, aff = c.get("velocity_feedforward", 0.0), c.get("acceleration_feedforward", 0.0)
        delay = Delay(c.get("computation_delay_samples", 1.0))

        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="drive")
        fmu.instantiate(callbacks=callbacks)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        # Parameters may be set here, e.g. fmu.setReal([vr["drive.preload_n"]], [80.0]).
        fmu.exitInitializationMode()

        pid = Pid(c, limit)
        sum_sq, peak, count = 0.0, 0.0, 0
        for k in range(n + 1):
            t = k * ts
            y, theta_o = fmu.getReal([feedback, vr["output_angle_rad"]])
            r, rate, accel = ref(t)
            u_ff = vff * ic * rate + aff * ic * accel
            u = pid.update(ic * r, scale * y, u_ff)
            if t >= start:
                e = (theta_o - r) * 1e3
                sum_sq, peak, count = sum_sq + e * e, max(peak, abs(e)), count + 1
            if k < n:
                first, second, split = delay.push(u)
                if split > 0.0:
                    fmu.setReal([command], [first])
                    fmu.doStep(currentCommunicationPoint=t, communicationStepSize=split * ts)
                    fmu.setReal([command], [second])
                    fmu.doStep(currentCommunicationPoint=t + split * ts, communicationStepSize=(1.0 - split) * ts)
                else:
                    fmu.setReal([command], [second])
                    fmu.doStep(currentCommunicationPoint=t, communicationStepSize=ts)
        fmu.terminate()
        fmu.freeInstance()
        return math.sqrt(sum_sq / count), peak, count
    finally:
        shutil.rmtree(unzipdir, ignore_errors=True)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    rms, peak, count = closed_loop(sys.argv[1])
    print(f"pointing error over {count} samples: rms {rms:.5f} mrad, peak {peak:.5f} mrad")
