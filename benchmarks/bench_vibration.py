"""Speed and accuracy of senscal.vibration against peers, as ratios measured in one run.

    python benchmarks/bench_vibration.py [--repeat N] [--threads N]

* response (double centrifuge, angle-synchronised three-parameter fit) vs a
  per-record ``scipy.optimize.curve_fit`` sine fit against the same angle;
* velocity point (four-parameter fit of the position, shared frequency,
  covariance propagation) vs ``curve_fit`` of both channels with a free
  frequency each;
* the whole ``senscal response`` path from CSV files vs a plain
  ``pandas.read_csv`` of the same files (how much the calibration adds to I/O).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import curve_fit

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from senscal.simulate.vibration import simulate_centrifuge, simulate_hydraulic  # noqa: E402
from senscal.vibration import cut_whole_revolutions, response_point, velocity_point  # noqa: E402


def best(fn, repeat):
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return min(ts), out


def sine(x, a, phi, c):
    return a * np.sin(x + phi) + c


def sine_f(t, a, f, phi, c):
    return a * np.sin(2 * np.pi * f * t + phi) + c


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=None,
                    help="Numba threads for the sine-fit kernels (on an oversubscribed machine 1 is much faster).")
    args = ap.parse_args()
    rep = args.repeat
    import numba

    if args.threads:
        numba.set_num_threads(args.threads)
    print(f"numba threads: {numba.get_num_threads()}")

    recs, truth = simulate_centrifuge(frequencies=(0.1, 0.5, 1, 2, 5, 10), seed=1)
    pts_truth = truth["points"]

    def ours():
        return [response_point(r["output"], r.time, input_amplitude=100.0, angle_deg=r["angle"],
                               static_sensitivity=0.05) for r in recs]

    def peer():
        out = []
        for r in recs:
            s = cut_whole_revolutions(r["angle"], r.time)  # same cut for both
            sl = slice(s.start, s.stop)
            psi = np.radians(np.unwrap(r["angle"][sl], period=360.0))
            y = r["output"][sl]
            p, cov = curve_fit(sine, psi, y, p0=[np.ptp(y) / 2, 0.0, y.mean()])
            out.append((abs(p[0]) / 100.0 / 0.05, p[1] - math.pi / 2, math.sqrt(cov[0, 0]) / 5.0))
        return out

    ours()  # compile the kernels outside the timing
    t_ours, res = best(ours, rep)
    t_peer, pres = best(peer, rep)
    err_ours = max(abs(p.normalized_sensitivity - tp["normalized_sensitivity"]) / p.u_normalized_sensitivity
                   for p, tp in zip(res, pts_truth))
    err_peer = max(abs(p[0] - tp["normalized_sensitivity"]) / p[2] for p, tp in zip(pres, pts_truth))
    print(f"centrifuge response, {len(recs)} records, {sum(r.n_samples for r in recs)} samples:")
    print(f"  senscal {t_ours * 1e3:8.2f} ms   curve_fit {t_peer * 1e3:8.2f} ms   speed ratio (peer/senscal) "
          f"{t_peer / t_ours:6.2f}")
    print(f"  max |S/S0 - truth| / u:  senscal {err_ours:.2f}   curve_fit {err_peer:.2f}")

    hrecs, htruth = simulate_hydraulic(seed=2)

    def ours_v():
        return [velocity_point(r["position"], r["velocity"], r.time) for r in hrecs]

    def peer_v():
        out = []
        for r, tp in zip(hrecs, htruth["points"]):
            f0 = tp["frequency_hz"] * 1.001
            pp, _ = curve_fit(sine_f, r.time, r["position"], p0=[0.02, f0, 0.0, 0.0])
            ps, _ = curve_fit(sine_f, r.time, r["velocity"], p0=[0.02, f0, 0.0, 0.0])
            out.append(abs(ps[0]) / (2 * np.pi * pp[1] * abs(pp[0])))
        return out

    ours_v()
    t_v, vres = best(ours_v, rep)
    t_pv, pv = best(peer_v, rep)
    print(f"hydraulic velocity points, {len(hrecs)} records:")
    print(f"  senscal {t_v * 1e3:8.2f} ms   curve_fit {t_pv * 1e3:8.2f} ms   speed ratio (peer/senscal) {t_pv / t_v:6.2f}")
    rms_o = math.sqrt(np.mean([(p.sensitivity - htruth["sensitivity"]) ** 2 for p in vres]))
    rms_p = math.sqrt(np.mean([(s - htruth["sensitivity"]) ** 2 for s in pv]))
    print(f"  RMS sensitivity error: senscal {rms_o:.3g}   curve_fit {rms_p:.3g} V/(m/s)")

    import pandas as pd

    from senscal.simulate.common import write_simulation
    from senscal.io import read_recording

    with tempfile.TemporaryDirectory() as d:
        paths = write_simulation(recs, truth, Path(d), "centrifuge")

        def read_only():
            return [pd.read_csv(p) for p in paths]

        def read_and_calibrate():
            out = []
            for p in paths:
                r = read_recording(p)
                out.append(response_point(r["output"], r.time, input_amplitude=100.0, angle_deg=r["angle"]))
            return out

        t_read, _ = best(read_only, rep)
        t_full, _ = best(read_and_calibrate, rep)
    print(f"from CSV files: pandas.read_csv {t_read * 1e3:.2f} ms, read + calibrate {t_full * 1e3:.2f} ms, "
          f"ratio {t_full / t_read:.2f}")


if __name__ == "__main__":
    main()
