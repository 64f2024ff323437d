"""Drift correction speed against a plain CSV read and filterpy, same data, one run.

    python benchmarks/bench_drift.py [--days 70] [--dt 60]

Simulates three drifting sensors (default 70 days at 1-min samples,
~1e5 samples), then times: reading the CSV (the floor any tool pays),
the augmented filter with given noise levels (redundant preset with the
temperature covariate: 5 states, time-varying H), the same with a 60-sample
window, the RTS smoother, the maximum-likelihood noise estimation, and
filterpy's loop on the same augmented model.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--days", type=float, default=70.0)
    ap.add_argument("--dt", type=float, default=60.0)
    args = ap.parse_args()

    from senscal.drift import DriftSetup, augmented_model, correct_drift, redundant_setup
    from senscal.drift.core import _starting_levels
    from senscal.io import read_recording, write_recording
    from senscal.simulate.drift import simulate_drift

    rec, truth = simulate_drift(days=args.days, dt=args.dt, seed=0)
    chans = ["ref", "drift", "thermal"]
    T = rec.n_samples
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "drift.csv"
        write_recording(rec, path)
        t0 = time.perf_counter()
        rec = read_recording(path)
        t_read = time.perf_counter() - t0
    y, t = rec.data(chans), rec.time
    cov = {"temperature": rec["temperature"]}
    base = redundant_setup(chans, trusted=["ref"], covariate="temperature")
    c = cov["temperature"] - cov["temperature"].mean()
    levels = _starting_levels(base, y, args.dt, float(t[-1]), {"temperature": c})
    given = DriftSetup(base.channels, base.signal.__class__(level=levels["signal_rate_std"]),
                       tuple(b.__class__(b.channel, b.covariate, b.reference, b.dynamics, levels[b.level_name], b.tau)
                             for b in base.biases),
                       noise_std={ch: levels[f"{ch}_noise_std"] for ch in chans}, trusted=base.trusted)
    small = max(1000, T // 100)
    correct_drift(given, y[:, :small], t[:small], {"temperature": cov["temperature"][:small]}, estimate=False)
    correct_drift(given, y[:, :small], t[:small], {"temperature": cov["temperature"][:small]}, estimate=False,
                  window=5)

    def timed(**kw):
        t0 = time.perf_counter()
        correct_drift(given, y, t, cov, estimate=False, **kw)
        return time.perf_counter() - t0

    t_filter = timed()
    t_window = timed(window=60)
    t_smooth = timed(smooth=True)
    n_ml = min(T, 20000)
    t0 = time.perf_counter()
    correct_drift(base, y[:, :n_ml], t[:n_ml], {"temperature": cov["temperature"][:n_ml]})
    t_ml = time.perf_counter() - t0

    from filterpy.kalman import KalmanFilter

    model = augmented_model(given, np.diff(t, prepend=t[0] - args.dt), levels, {"temperature": c})
    kf = KalmanFilter(dim_x=model.n_states, dim_z=3)
    kf.F, kf.Q, kf.R = model.F, model.Q, model.R
    kf.x = np.zeros((model.n_states, 1))
    kf.P = np.eye(model.n_states) * 100.0
    from senscal.kalman import kalman_filter

    kalman_filter(model, y[:, :10] if model.n_steps is None else y)  # compile / load cache
    t0 = time.perf_counter()
    kalman_filter(model, y)
    t_engine = time.perf_counter() - t0
    t0 = time.perf_counter()
    for k in range(T):
        if k > 0:
            kf.predict()
        kf.update(y[:, k], H=model.H[k])
    t_fp = time.perf_counter() - t0

    print(f"Drift correction, 3 sensors + covariate, {T:,} samples (5 augmented states, time-varying H)")
    print(f"  read CSV (floor):                    {t_read:8.3f} s")
    print(f"  filter + CUSUM detection:            {t_filter:8.3f} s   {t_filter / t_read:6.2f}x the CSV read")
    print(f"  window L=60 (fixed lag):             {t_window:8.3f} s   {t_window / t_read:6.2f}x the CSV read")
    print(f"  RTS smoother:                        {t_smooth:8.3f} s   {t_smooth / t_read:6.2f}x the CSV read")
    print(f"  ML noise levels + filter, {n_ml:,} samples: {t_ml:8.3f} s")
    print(f"  senscal engine, filter only:         {t_engine:8.3f} s")
    print(f"  filterpy loop, filter only:          {t_fp:8.3f} s   {t_fp / t_engine:.1f}x the engine's time, "
          f"{t_fp / t_filter:.1f}x senscal's filter + detection")


if __name__ == "__main__":
    main()
