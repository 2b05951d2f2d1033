#!/usr/bin/env python3
"""Independent check of a tuned design's margins with python-control.

Reads the results directory of `cable-servo design tune` (tuned.toml and summary.json),
builds the loop from the scenario's values alone (motor and drum on the cable's two
linear halves, current amplifier, zero-order hold by python-control, whole samples of
computation delay, the PID as implemented: integral by forward sums, derivative on the
measurement through its first-order filter) at each stiffness of the operating range the
tune reports, and checks what an engineer signs: a stable closed loop, every phase margin
>= the required one, every gain margin (up and down) >= the required one in dB, and the
sensitivity peak <= the required one. It also compares its figures with the tune's own.

Usage: check_tune_margins.py RESULTS_DIR
Exit 0 when the pick is signable here too, 1 when it is not, 2 when the check cannot run.
"""

import json
import math
import sys
import tomllib

try:
    import numpy as np
    import control
except ImportError as e:  # the test that runs this turns the message into its failure
    print(
        f"python-control is missing ({e}); install it with: python3 -m pip install control",
        file=sys.stderr,
    )
    sys.exit(2)


def loop_gain(scn, half_k, free_k):
    """Discrete loop gain L(z) = K(z) P(z) z^-m broken at the plant input."""
    drive = scn["drive"]
    cl = scn["closed_loop"]
    motor, out, ctl = cl["motor"], cl["output"], cl["controller"]
    if motor.get("amplifier", "current") != "current":
        raise SystemExit("check_tune_margins: only a current amplifier is modelled here")
    ri, ro = drive["pulley_radius_m"], drive["drum_radius_m"]
    jm, bm = motor["inertia_kg_m2"], motor.get("viscous_nm_s_per_rad", 0.0)
    kt = motor["torque_constant_nm_per_a"]
    jo, bo = out["inertia_kg_m2"], out.get("viscous_nm_s_per_rad", 0.0)
    # Structural damping of each half, from the free span's cable mode and its ratio.
    inv_m = ri * ri / jm + ro * ro / jo
    zeta = cl.get("cable_damping_ratio", 0.0)
    c = zeta * math.sqrt(2.0 * free_k * inv_m) / inv_m
    k = half_k
    # States: motor angle, motor rate, drum angle, drum rate. F = Tu - Tl.
    f = [2 * k * ri, 2 * c * ri, -2 * k * ro, -2 * c * ro]
    a = np.zeros((4, 4))
    a[0, 1] = 1.0
    a[2, 3] = 1.0
    for j in range(4):
        a[1, j] = -ri * f[j] / jm
        a[3, j] = ro * f[j] / jo
    a[1, 1] -= bm / jm
    a[3, 3] -= bo / jo
    b = np.array([[0.0], [kt / jm], [0.0], [0.0]])
    ic = ro / ri
    feedback = ctl.get("feedback", "motor")
    if feedback == "motor":
        cm = np.array([[1.0, 0.0, 0.0, 0.0]])
    elif feedback == "output":
        cm = np.array([[0.0, 0.0, ic, 0.0]])
    else:
        raise SystemExit(f"check_tune_margins: feedback {feedback} is not modelled here")
    ts = 1.0 / ctl["sample_rate_hz"]
    plant = control.c2d(control.ss(a, b, cm, np.zeros((1, 1))), ts, method="zoh")
    delay = ctl.get("computation_delay_samples", 1.0)
    if abs(delay - round(delay)) > 1e-12:
        raise SystemExit("check_tune_margins: only whole samples of delay are modelled here")
    z = control.tf([1.0, 0.0], [1.0], ts)
    kp, ki, kd = ctl["kp"], ctl["ki"], ctl["kd"]
    ad = math.exp(-2 * math.pi * ctl["derivative_filter_hz"] * ts)
    pid = kp + ki * ts * z / (z - 1) + (1 - ad) * (kd / ts) * (z - 1) / (z - ad)
    lg = pid * control.ss2tf(plant)
    for _ in range(int(round(delay))):
        lg = lg / z
    return lg, ts


def judge(lg, ts, req):
    """Stability, every crossing and Ms, on python-control's own routines."""
    cl = control.feedback(lg, 1)
    rho = max(abs(p) for p in cl.poles())
    nyq = math.pi / ts
    w = np.logspace(math.log10(2 * math.pi * 0.1), math.log10(nyq * 0.9999), 20000)
    # The frequency-data method: the polynomial one finds spurious crossings near z = 1,
    # where the loop's three poles (two rigid-body, one integral) make the polynomials
    # ill-conditioned; on the unit circle the response itself is accurate.
    gm, pm, sm, wpc, wgc, wms = control.stability_margins(
        control.frd(lg, w), returnall=True
    )
    gm_db = [20 * math.log10(g) for g in np.atleast_1d(gm) if np.isfinite(g) and g > 0]
    # python-control measures the phase unwrapped from low frequency (below -360 deg for
    # this loop, which starts at -270 deg); the margin is the distance to the nearest
    # -180 deg + k 360 deg.
    pms = [abs(((p + 180.0) % 360.0) - 180.0) for p in np.atleast_1d(pm) if np.isfinite(p)]
    resp = lg(np.exp(1j * w * ts))
    ms = float(np.max(np.abs(1.0 / (1.0 + resp))))
    up = [g for g in gm_db if g > 0]
    down = [-g for g in gm_db if g < 0]
    return {
        "spectral_radius": rho,
        "stable": rho < 1.0,
        "phase_margin_deg": min(pms) if pms else None,
        "gain_margin_up_db": min(up) if up else None,
        "gain_margin_down_db": min(down) if down else None,
        "ms": ms,
        "crossings": {"phase_margins_deg": pms, "gain_margins_db": gm_db},
    }


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    d = sys.argv[1]
    with open(f"{d}/summary.json") as fh:
        summary = json.load(fh)
    with open(f"{d}/tuned.toml", "rb") as fh:
        scn = tomllib.load(fh)
    pick = summary.get("pick")
    if not pick:
        print("check_tune_margins: the tune has no pick", file=sys.stderr)
        return 1
    req = scn["closed_loop"].get("requirements", {})
    pm_min = req.get("min_phase_margin_deg", 35.0)
    gm_min = req.get("min_gain_margin_db", 6.0)
    ms_max = req.get("max_ms", 2.0)
    free_k = pick["margins"][0]["half_stiffness_n_per_m"]
    ok = True
    for point in pick["margins"]:
        lg, ts = loop_gain(scn, point["half_stiffness_n_per_m"], free_k)
        got = judge(lg, ts, req)
        misses = []
        if not got["stable"]:
            misses.append(f"unstable (largest pole |z| = {got['spectral_radius']:.6f})")
        else:
            if got["phase_margin_deg"] is None or got["phase_margin_deg"] < pm_min:
                misses.append(f"phase margin {got['phase_margin_deg']} deg < {pm_min}")
            for key in ("gain_margin_up_db", "gain_margin_down_db"):
                if got[key] is not None and got[key] < gm_min:
                    misses.append(f"{key} {got[key]:.3f} dB < {gm_min}")
            if got["ms"] > ms_max:
                misses.append(f"Ms {got['ms']:.4f} > {ms_max}")
        print(
            f"{point['condition']}: python-control PM {fmt(got['phase_margin_deg'])} deg "
            f"(tune {fmt(point['phase_margin_deg'])}), GM up {fmt(got['gain_margin_up_db'])} dB "
            f"(tune {fmt(point['gain_margin_up_db'])}), GM down {fmt(got['gain_margin_down_db'])} dB "
            f"(tune {fmt(point['gain_margin_down_db'])}), Ms {fmt(got['ms'], 4)} "
            f"(tune {fmt(point['ms'], 4)}), largest closed-loop pole {got['spectral_radius']:.6f}: "
            + ("signable" if not misses else "NOT signable: " + "; ".join(misses))
        )
        ok = ok and not misses
    return 0 if ok else 1


def fmt(v, digits=2):
    return "-" if v is None else f"{v:.{digits}f}"


if __name__ == "__main__":
    sys.exit(main())
