"""Speed of the shaft calibration and compensation against a streaming read and a peer fit.

Run: ``python benchmarks/bench_shaft.py [--log2n 21]``.  Prints, in one run on
the same simulated record, the time of a plain streaming pass over the two
channels (``np.sum``), of ``calibrate_gravity`` (plain three-parameter fit
and with the ripple regression), of ``scipy.optimize.curve_fit`` on the same
plain model (the peer; its answer is compared too), and of ``compensate``,
with their ratios.
"""

from __future__ import annotations

import argparse
import math
import timeit

import numpy as np
from scipy.optimize import curve_fit

from senscal.shaft import calibrate_gravity, compensate
from senscal.simulate.shaft import simulate_shaft
from senscal.sinefit import fit_sine


def best_of(fn, repeat=3):
    """(best wall time in s, result) over ``repeat`` calls."""
    out = []
    best = min(timeit.repeat(lambda: out.append(fn()), number=1, repeat=repeat))
    return best, out[-1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--log2n", type=int, default=21)
    args = ap.parse_args()
    n = 2**args.log2n
    fs = 1000.0
    cal, test, truth = simulate_shaft(cal_duration=n / fs, test_duration=n / fs, seed=0)
    a, ang, t = np.asarray(cal["accel"]), np.asarray(cal["angle"]), cal.time
    th = np.radians(np.unwrap(ang, period=360.0))
    calibrate_gravity(a[:5000], ang[:5000], t[:5000], angle_unit="deg")  # warm up (numba compile)

    t_read, _ = best_of(lambda: a.sum() + ang.sum())
    t_plain, m0 = best_of(lambda: calibrate_gravity(a, ang, t, angle_unit="deg", ripple_correction=False))
    t_reg, m1 = best_of(lambda: calibrate_gravity(a, ang, t, angle_unit="deg"))

    t_core, core = best_of(lambda: fit_sine(a, th, freq=1 / (2 * math.pi)))

    def peer():
        return curve_fit(lambda x, amp, ph, off: amp * np.sin(x + ph) + off, th, a, p0=[9.0, 0.5, 0.0])

    t_cf, (p, _) = best_of(peer, repeat=1)
    t_comp, res = best_of(lambda: compensate(m1, test["accel"], test["angle"], test.time, radius=truth["radius"],
                                             angle_unit="deg", remove_centripetal=True))
    g = truth["gravity"]
    mb = 2 * a.nbytes / 1e6
    print(f"record: 2^{args.log2n} samples x 2 channels ({mb:.0f} MB), {n / fs / 3600:.2f} h at {fs:g} Hz")
    print(f"streaming read (np.sum)                 {t_read * 1e3:9.1f} ms")
    print(f"calibrate, plain 3-parameter fit        {t_plain * 1e3:9.1f} ms   ratio to read {t_plain / t_read:7.1f}x")
    print(f"calibrate, with ripple regression       {t_reg * 1e3:9.1f} ms   ratio to read {t_reg / t_read:7.1f}x")
    print(f"  of which the sine fit against angle   {t_core * 1e3:9.1f} ms")
    print(f"scipy curve_fit, same plain model       {t_cf * 1e3:9.1f} ms   speed-up of the sine fit: "
          f"{t_cf / t_core:.1f}x, of the whole plain calibration: {t_cf / t_plain:.2f}x")
    print(f"compensate + encoder check + leakage    {t_comp * 1e3:9.1f} ms   ratio to read {t_comp / t_read:7.1f}x")
    # Same data, same abscissa (calibrate itself fits against the smoothed angle).
    print(f"sine fit vs curve_fit on the raw angle: amplitude {abs(core.amplitude - p[0]):.2e}, phase "
          f"{abs(math.remainder(core.phase - p[1], 2 * math.pi)):.2e} rad, offset {abs(core.offset - p[2]):.2e}")
    print(f"accuracy (ripple regression): amplitude {(m1.amplitude - g['amplitude']) / m1.u_amplitude:+.2f} u, "
          f"phase {math.remainder(m1.phase - math.radians(g['phase_deg']), 2 * math.pi) / m1.u_phase:+.2f} u, "
          f"offset {(m1.offset - g['offset']) / m1.u_offset:+.2f} u")
    print(f"accuracy (plain fit, 3% ripple):    amplitude {(m0.amplitude - g['amplitude']) / m0.u_amplitude:+.2f} u")


if __name__ == "__main__":
    main()
