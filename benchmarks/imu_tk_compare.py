"""Gravity-direction residual on an IMU-TK session: senscal's gyro fit beside IMU-TK's approach.

IMU-TK (Tedaldi et al., ICRA 2014) takes the gyro bias as the mean of the still start, fits the gyro's
scale and misalignment by unweighted least squares on the difference between the gravity direction
integrated (RK4) from one static pose to the next and the one the calibrated accelerometer measures there.
This script runs senscal's job on the same poses and then that approach (same poses, same accelerometer
calibration, same integrator: only the bias and the weighting differ) and prints the per-rotation rms of
both.

Run: ``python benchmarks/imu_tk_compare.py ACC.txt GYRO.txt [--init 50]`` (IMU-TK's text files:
time and three axes per line, sample for sample).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from scipy import optimize


def main(argv=None) -> int:
    from senscal.imu import calibrate_imu
    from senscal.imu.calibrate import _GyroProblem
    from senscal.imu.terms import BiasDesign

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("acc")
    ap.add_argument("gyro")
    ap.add_argument("--init", type=float, default=50.0, help="still start, s")
    ap.add_argument("--g-sensitivity", action="store_true", help="senscal's fit with g-sensitivity")
    a = ap.parse_args(argv)
    acc, gyr = np.loadtxt(a.acc), np.loadtxt(a.gyro)
    t = acc[:, 0]
    r = calibrate_imu(t, acc[:, 1:].T, gyr[:, 1:].T, init_s=a.init, g_sensitivity=a.g_sensitivity)
    st = r.poses.static
    g = gyr[:, 1:].T
    n0 = int(np.searchsorted(t, t[0] + a.init))
    bias = g[:, :n0].mean(axis=1)  # IMU-TK: the still start's mean, constant
    design = BiasDesign(t_ref=0.0, temp_ref=None, degree=0, g_sensitivity=False)
    prob = _GyroProblem(t, g, st.starts, st.stops, st.means, r.gravity,
                        lambda idx: design.matrix(t[idx], None, None))
    nu = np.concatenate([r.accel_values, bias, np.zeros(3)])
    s0 = float(np.mean(np.abs(np.diag(r.gyroscope.matrix))))

    def fun(x):
        return prob.raw(x.reshape(3, 3) * s0, nu)

    sol = optimize.least_squares(fun, np.eye(3).ravel(), method="lm", x_scale="jac")
    tk = prob.angles_deg(sol.x.reshape(3, 3) * s0, nu)
    rms = lambda x: float(np.sqrt(np.mean(np.asarray(x) ** 2)))  # noqa: E731
    print(f"{st.n_poses} poses, {tk.size} rotations")
    print(f"senscal{' (--g-sensitivity)' if a.g_sensitivity else ''}: rms {rms(r.residual_after_deg):.3f} deg, "
          f"median {float(np.median(r.residual_after_deg)):.3f} deg")
    print(f"IMU-TK approach (still-start bias, unweighted): rms {rms(tk):.3f} deg, median {float(np.median(tk)):.3f} deg")
    print(f"nominal gyro: rms {rms(r.residual_before_deg):.3f} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
