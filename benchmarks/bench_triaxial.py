"""Speed of senscal.triaxial, as ratios against baselines measured in the same run.

Run: ``python benchmarks/bench_triaxial.py`` (from the repository root).

* full calibration (diagnostics + ellipsoid + maximum likelihood) of N
  readings vs a plain pandas read of the same readings from CSV;
* the compiled LMS neuron vs the same rule in a Python loop;
* static-pose detection on the IMU-TK recording vs ``numpy.loadtxt`` of it.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from senscal.io import write_recording  # noqa: E402
from senscal.simulate.triaxial import simulate_magnetometer  # noqa: E402
from senscal.triaxial import calibrate, detect_static, fit_lms  # noqa: E402
from senscal.triaxial.estimators import _linear_problem  # noqa: E402


def best(fn, repeat=3):
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def lms_python(x, y, lr, epochs):
    w = np.zeros(x.shape[1])
    for _ in range(epochs):
        for t in range(x.shape[0]):
            e = y[t] - x[t] @ w
            w += lr * e * x[t]
    return w


def main() -> None:
    print("senscal.triaxial benchmark (ratio < 1: senscal faster than the baseline)")
    with tempfile.TemporaryDirectory() as d:
        for n in (1_000, 20_000, 100_000):
            rec, _ = simulate_magnetometer(motion="sphere", n=n, seed=1)
            path = write_recording(rec, Path(d) / f"m{n}.csv")
            h = rec.data()
            calibrate(h, field=50_000.0)  # warm-up
            t_cal = best(lambda: calibrate(h, field=50_000.0), repeat=2)
            t_read = best(lambda: pd.read_csv(path))
            print(f"  calibrate full/ml, N={n:>7}: {t_cal * 1e3:8.1f} ms   pandas.read_csv: {t_read * 1e3:8.1f} ms"
                  f"   ratio {t_cal / t_read:6.2f}")
    rec, _ = simulate_magnetometer(motion="sphere", n=500, seed=2)
    h = rec.data()
    x, y, _, _ = _linear_problem(h, 50_000.0, "full")
    fit_lms(h, field=50_000.0)  # compile
    t_nb = best(lambda: fit_lms(h, field=50_000.0, epochs=50))
    t_py = best(lambda: lms_python(x, y, 0.01, 50), repeat=1)
    w_nb = fit_lms(h, field=50_000.0).values
    print(f"  LMS 500 x 50 epochs: numba {t_nb * 1e3:.2f} ms   python loop {t_py * 1e3:.1f} ms   ratio "
          f"{t_nb / t_py:.4f}")
    data = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "imu_tk_xsens_acc.txt"
    if data.exists():
        arr = np.loadtxt(data)
        xs = arr[:, 1:].T.copy()
        t_st = best(lambda: detect_static(xs, 100.0))
        t_lt = best(lambda: np.loadtxt(data), repeat=1)
        st = detect_static(xs, 100.0)
        t_c = best(lambda: calibrate(st.means - 32768.0, field=9.81744))
        print(f"  static detection, {xs.shape[1]} samples: {t_st * 1e3:.1f} ms   numpy.loadtxt: {t_lt * 1e3:.1f} ms"
              f"   ratio {t_st / t_lt:.3f}; calibration of {st.n_poses} poses {t_c * 1e3:.1f} ms")
    else:
        print(f"  (IMU-TK recording not found at {data}; static-detection benchmark skipped)")
    del w_nb


if __name__ == "__main__":
    main()
