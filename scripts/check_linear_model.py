#!/usr/bin/env python3
"""Independent check of `cable-servo margins` with python-control.

Reads linear_model.json from a results directory of `cable-servo margins`, rebuilds at
every operating point the loop L(z) = K(z) P(z) from the exported discrete plant
(plant.sampled: A, B, C, D at the control period) and the exported controller
(numerator and denominator in z^-1, computation delay included) as python-control
systems, and from them alone finds every gain crossover (|L| = 1) and every phase
crossover (L on the negative real axis) below Nyquist, the sensitivity peak and the
closed loop's largest pole. Each crossing must match the tool's: the same number of
crossings, each frequency within 0.1 %, each phase margin within 0.1 deg and each gain
margin within 0.1 dB. The exported loop response must equal python-control's L at the
same frequencies.

Usage: check_linear_model.py RESULTS_DIR
Exit 0 when python-control reproduces every margin, 1 when it does not, 2 when the check
cannot run.
"""

import json
import math
import sys

try:
    import numpy as np
    import control
    from scipy.optimize import brentq
except ImportError as e:  # the test that runs this turns the message into its failure
    print(
        f"python-control is missing ({e}); install it with: python3 -m pip install control",
        file=sys.stderr,
    )
    sys.exit(2)

PM_TOL_DEG = 0.1
GM_TOL_DB = 0.1
F_TOL = 1e-3


def loop(point, ts):
    """L(z) = K(z) P(z) as a python-control system, from the exported numbers alone."""
    s = point["plant"]["sampled"]
    plant = control.ss(
        np.array(s["a"]), np.array(s["b"]), np.array(s["c"]), np.array(s["d"]), ts
    )
    k = point["controller"]
    num, den = list(k["numerator_z_inv"]), list(k["denominator_z_inv"])
    # A polynomial in z^-1 padded to a common length reads as one in z.
    n = max(len(num), len(den))
    num += [0.0] * (n - len(num))
    den += [0.0] * (n - len(den))
    return control.series(control.tf(num, den, ts), plant)


def crossings(lg, ts, f_lo, f_hi):
    """Every crossing of |L| = 1 and of the negative real axis on (f_lo, f_hi)."""
    f = np.geomspace(f_lo, f_hi, 50_000)

    def ev(x):
        return complex(lg(np.exp(2j * math.pi * x * ts)))

    resp = lg(np.exp(2j * math.pi * f * ts))
    mag = np.abs(resp) - 1.0
    gains, phases = [], []
    for i in np.nonzero(np.sign(mag[:-1]) != np.sign(mag[1:]))[0]:
        fc = brentq(lambda x: abs(ev(x)) - 1.0, f[i], f[i + 1], xtol=1e-12, rtol=1e-14)
        gains.append((fc, 180.0 - abs(math.degrees(np.angle(ev(fc))))))
    im = resp.imag
    for i in np.nonzero(np.sign(im[:-1]) != np.sign(im[1:]))[0]:
        if resp.real[i] >= 0 and resp.real[i + 1] >= 0:
            continue
        fc = brentq(lambda x: ev(x).imag, f[i], f[i + 1], xtol=1e-12, rtol=1e-14)
        v = ev(fc)
        if v.real < 0:
            db = 20 * math.log10(abs(v))
            phases.append((fc, abs(db), "up" if db < 0 else "down"))
    ms = float(np.max(1.0 / np.abs(1.0 + resp)))
    return gains, phases, ms


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    with open(f"{sys.argv[1]}/linear_model.json") as fh:
        model = json.load(fh)
    ts = 1.0 / model["sample_rate_hz"]
    ok = True
    for point in model["operating_points"]:
        name = point["condition"]
        if point["controller"] is None:
            print(f"{name}: no controller coefficients (not a plain PID): cannot rebuild")
            return 2
        lg = loop(point, ts)
        m = point["margins"]
        rho = max(abs(p) for p in control.feedback(lg, 1).poles())
        misses = []
        if (rho < 1.0) != m["stable"]:
            misses.append(f"stability: python-control |z| max {rho:.6f}, tool {m['spectral_radius']:.6f}")
        r = point["loop_response"]
        fr = np.array(r["freq_hz"])
        exported = np.array(r["re"]) + 1j * np.array(r["im"])
        mine = lg(np.exp(2j * math.pi * fr * ts))
        rel = float(np.max(np.abs(mine - exported) / np.abs(exported)))
        if rel > 1e-6:
            misses.append(f"loop_response differs from python-control's L by {rel:.2e} (relative)")
        worst_pm = worst_gm = 0.0
        if m["stable"]:
            gains, phases, ms = crossings(lg, ts, fr[0], fr[-1])
            tool_g = m["gain_crossovers"]
            tool_p = m["phase_crossovers"]
            if len(gains) != len(tool_g):
                misses.append(f"{len(gains)} gain crossovers, the tool lists {len(tool_g)}")
            else:
                for (f, pm), t in zip(gains, tool_g):
                    worst_pm = max(worst_pm, abs(pm - t["phase_margin_deg"]))
                    if abs(f / t["frequency_hz"] - 1) > F_TOL or abs(pm - t["phase_margin_deg"]) > PM_TOL_DEG:
                        misses.append(
                            f"gain crossover {f:.4f} Hz PM {pm:.3f} deg, tool {t['frequency_hz']:.4f} Hz PM {t['phase_margin_deg']:.3f} deg"
                        )
            if len(phases) != len(tool_p):
                misses.append(f"{len(phases)} phase crossovers, the tool lists {len(tool_p)}")
            else:
                for (f, gm, d), t in zip(phases, tool_p):
                    worst_gm = max(worst_gm, abs(gm - t["gain_margin_db"]))
                    if (
                        abs(f / t["frequency_hz"] - 1) > F_TOL
                        or abs(gm - t["gain_margin_db"]) > GM_TOL_DB
                        or d != t["direction"]
                    ):
                        misses.append(
                            f"phase crossover {f:.4f} Hz GM {gm:.3f} dB {d}, tool {t['frequency_hz']:.4f} Hz GM {t['gain_margin_db']:.3f} dB {t['direction']}"
                        )
            if abs(ms / m["ms"] - 1) > 1e-3:
                misses.append(f"Ms {ms:.5f}, tool {m['ms']:.5f}")
            listing = "; ".join(
                [f"{f:.4g} Hz PM {pm:.3f} deg" for f, pm in gains]
                + [f"{f:.4g} Hz GM {d} {gm:.3f} dB" for f, gm, d in phases]
            )
            print(f"{name}: python-control finds {listing}; Ms {ms:.4f}; largest pole |z| {rho:.6f}")
            print(
                f"{name}: largest difference to the tool: {worst_pm:.2e} deg of phase margin, "
                f"{worst_gm:.2e} dB of gain margin; loop response {rel:.1e} relative: "
                + ("agrees" if not misses else "DIFFERS: " + "; ".join(misses))
            )
        else:
            print(f"{name}: unstable (largest pole |z| {rho:.6f}): " + ("agrees" if not misses else "DIFFERS: " + "; ".join(misses)))
        ok = ok and not misses
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
