"""Speed of the gyro-free pipeline on the paper's data size: 10 kHz x 10 s x 12 channels.

Prints the pipeline time against the time to load the same data (CSV and
NPZ) and against filterpy's extended Kalman filter on the same model,
all measured in this run.  Run: ``python benchmarks/bench_gfimu.py``.
``python benchmarks/bench_gfimu.py --seeds 20`` prints instead the accuracy
table of the ``--paper`` simulation over seeds 0..19 (plain EKF, the EKF
with the constant-error states, and that one smoothed offline).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np


def best(fn, repeat=3):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> None:
    from senscal.gfimu import METHODS, angular_velocity, integrate_attitude, paper_layout
    from senscal.io import read_recording, write_recording
    from senscal.simulate.gfimu import simulate_gfimu

    rec, truth, _ = simulate_gfimu(paper=True, seed=0)
    layout = paper_layout(0.04)
    names = list(layout.names)
    with tempfile.TemporaryDirectory() as d:
        csv, npz = Path(d) / "a.csv", Path(d) / "a.npz"
        write_recording(rec, csv)
        write_recording(rec, npz)
        t_csv, _ = best(lambda: read_recording(csv).data(names), 2)
        t_npz, _ = best(lambda: read_recording(npz).data(names))
    y, t = rec.data(names), rec.time
    angular_velocity(y[:, :1000], t[:1000], layout, methods=METHODS)  # compile / warm caches

    def kalman_only(**kw):
        est = angular_velocity(y, t, layout, methods=("kalman",), **kw)
        return integrate_attitude(est.omega["kalman"], t)

    t_d, _ = best(kalman_only)
    t_k, _ = best(lambda: kalman_only(plain=True))
    t_all, _ = best(lambda: angular_velocity(y, t, layout, methods=METHODS, plain=True))
    t_sqrt, _ = best(lambda: angular_velocity(y, t, layout, methods=("kalman",), observation="sqrt"))
    t_off, _ = best(lambda: angular_velocity(y, t, layout, methods=("kalman",), bias_std=1e-4 * 9.80665))  # = default
    t_sm, _ = best(lambda: angular_velocity(y, t, layout, methods=("kalman",), bias_std=1e-4 * 9.80665, smooth=True))

    # filterpy's EKF on the same model, timed on 5000 steps and scaled.
    from filterpy.kalman import ExtendedKalmanFilter

    from senscal.gfimu import solve_kinematics
    from senscal.gfimu.filter import channel_covariance
    from senscal.gfimu.methods import estimate_noise_std, rate_increments

    kin = solve_kinematics(y, layout)
    C = channel_covariance(kin, estimate_noise_std(y))
    inc = rate_increments(kin.angular_acceleration, t)

    def hx(x):
        a, b, c = x
        return np.array([-(b * b + c * c), -(a * a + c * c), -(a * a + b * b), a * b, a * c, b * c])

    def jac(x):
        a, b, c = x
        return np.array([[0, -2 * b, -2 * c], [-2 * a, 0, -2 * c], [-2 * a, -2 * b, 0], [b, a, 0], [c, 0, a],
                         [0, c, b]])

    def fp(n=5000):
        ekf = ExtendedKalmanFilter(dim_x=3, dim_z=6, dim_u=3)
        ekf.x, ekf.P, ekf.B = np.zeros(3), np.eye(3) * 1e-6, np.eye(3)
        ekf.Q, ekf.R = (t[1] - t[0]) ** 2 * C[3:6, 3:6], C[6:12, 6:12]
        for k in range(n):
            if k:
                ekf.predict(u=inc[:, k])
            ekf.update(kin.W[:, k], jac, hx)

    t_fp5, _ = best(fp, 1)
    t_fp = t_fp5 * t.size / 5000
    n = t.size
    print(f"data: {y.shape[0]} channels x {n} samples (10 kHz x 10 s)")
    print(f"load CSV                      {t_csv * 1e3:9.1f} ms")
    print(f"load NPZ                      {t_npz * 1e3:9.1f} ms")
    print(f"pipeline default (EKF + 9 constant-error states) + attitude "
          f"{t_d * 1e3:9.1f} ms   = {t_d / t_csv:6.3f} x CSV load, {t_d / t_npz:6.2f} x NPZ load")
    print(f"pipeline --plain EKF+attitude {t_k * 1e3:9.1f} ms   = {t_k / t_csv:6.3f} x CSV load, {t_k / t_npz:6.2f} x NPZ load")
    print(f"pipeline all four methods (plain) {t_all * 1e3:9.1f} ms   = {t_all / t_csv:6.3f} x CSV load, {t_all / t_npz:6.2f} x NPZ load")
    print(f"pipeline kalman (sqrt, engine){t_sqrt * 1e3:9.1f} ms   = {t_sqrt / t_csv:6.3f} x CSV load")
    print(f"pipeline kalman EKF+offsets   {t_off * 1e3:9.1f} ms   = {t_off / t_csv:6.3f} x CSV load, {t_off / t_npz:6.2f} x NPZ load")
    print(f"  ... + offline RTS smoother  {t_sm * 1e3:9.1f} ms   = {t_sm / t_csv:6.3f} x CSV load, {t_sm / t_npz:6.2f} x NPZ load")
    print(f"filterpy EKF (scaled from 5000 steps) {t_fp * 1e3:9.1f} ms: senscal plain EKF pipeline (same 3-state "
          f"model) is {t_fp / t_k:6.1f}x faster, the default 12-state pipeline {t_fp / t_d:6.1f}x")


def seeds(n: int) -> None:
    """Accuracy on the ``--paper`` simulation over seeds 0..n-1: the filter's gain over each method."""
    from senscal.gfimu import METHODS, angular_velocity, error_statistics, paper_layout
    from senscal.simulate.gfimu import G0, simulate_gfimu

    singles = ("integration", "sqrt", "differential")
    print("vibrating axis z: ratio single-method error / Kalman error (max |e| and std), "
          "plain EKF > EKF+offsets (causal) > EKF+offsets smoothed (offline)")
    print("seed cancel | " + " ".join(f"max/{m[:5]:5s}" for m in singles) + " | " + " ".join(f"std/{m[:5]:5s}" for m in singles)
          + " | z-score std")
    count = {None: 0, "offsets": 0, "smoothed": 0}
    for s in range(n):
        rec, tr, info = simulate_gfimu(paper=True, seed=s)
        b = info["bias_m_s2"]
        cancel = abs(b["a2y"] - b["a1y"] - b["a3x"] + b["a1x"]) < 1e-12
        w = tr.data(["wx", "wy", "wz"])
        cells = []
        for key, bias_std, smooth in ((None, None, False), ("offsets", 1e-4 * G0, False),
                                      ("smoothed", 1e-4 * G0, True)):
            est = angular_velocity(rec.data(), rec.time, paper_layout(), methods=METHODS, bias_std=bias_std,
                                   smooth=smooth, plain=key is None)
            st = error_statistics(est.omega, w)
            k = st["kalman"]
            r = [st[m].max_abs_error[2] / k.max_abs_error[2] for m in singles] + \
                [st[m].std_error[2] / k.std_error[2] for m in singles]
            z = ((est.omega["kalman"][2] - w[2]) / est.u_omega[2]).std()
            count[key] += all(v >= 10 for v in r)
            cells.append((r, z))
        (r0, z0), (r1, z1), (r2, z2) = cells
        trip = [f"{a:.1f}>{b:.1f}>{c:.1f}" for a, b, c in zip(r0, r1, r2)]
        print(f"{s:4d} {'yes' if cancel else 'no':6s} | " + " ".join(trip[:3]) + " | " + " ".join(trip[3:])
              + f" | {z0:.2f}>{z1:.2f}>{z2:.2f}")
    print(f"seeds with every ratio >= 10: plain EKF {count[None]}/{n}, EKF+offsets {count['offsets']}/{n}, "
          f"smoothed {count['smoothed']}/{n}")


if __name__ == "__main__":
    import sys

    if len(sys.argv) > 2 and sys.argv[1] == "--seeds":
        seeds(int(sys.argv[2]))
    else:
        main()
