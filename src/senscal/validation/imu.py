"""Monte-Carlo coverage of ``senscal imu calibrate`` (issue 27).

Each seed simulates a multi-pose session (:func:`senscal.simulate.imu.simulate_imu`: 20 s still start,
30 poses of 3 s joined by 1.5 s rotations about random axes, 100 Hz, MEMS noise 0.02 m/s^2 and
0.002 rad/s per sample), calibrates it and checks every quoted number against the truth at k = 2:
accelerometer gains, angles and offsets, gyro scales (signed row norms of ``M_g``), the six gyro
misalignment angles and the gyro bias at the reported time.

Scenarios: ``white``; ``bias-drift`` (gyro bias drifting 2e-5 rad/s per s on each axis: modelled, must
cover); ``coloured-gyro`` (AR(1) 0.95 gyro noise: the rotations' residuals exceed the white-noise model,
``gyro-residuals-inconsistent`` must fire); ``axis-unexcited`` (no rotation about Z: ``gyro-axis-unexcited``
must fire).
"""

from __future__ import annotations

import math

import numpy as np

from senscal.diagnostics import has_warning
from senscal.validation import CoverageRow, coverage_row

__all__ = ["SCENARIOS", "run_white", "run_bias_drift", "run_coloured", "run_unexcited"]

JOB = "imu"


def _one(seed: int, sim_kw: dict):
    from senscal.imu import ACCEL_NAMES, GYRO_ANGLES, calibrate_imu
    from senscal.simulate.imu import simulate_imu

    rec, tr = simulate_imu(seed=seed, **sim_kw)
    r = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s")
    g, tg = r.gyroscope, tr["gyroscope"]
    out = {}
    ua = np.sqrt(np.clip(np.diag(r.accel_covariance), 0, None))
    for i, n in enumerate(ACCEL_NAMES):
        out[f"accel_{n}"] = (r.accel_values[i], ua[i], tr["accelerometer"][n])
    for i, a in enumerate("xyz"):
        out[f"gyro_scale_{a}"] = (g.scale[i], g.u_scale[i], tg[f"scale_{a}"])
    for i, n in enumerate(GYRO_ANGLES):
        out[f"gyro_angle_{n}"] = (g.angles[i], g.u_angles[i], tg[f"angle_{n}"])
    bt = np.asarray(tg["bias"]) + np.asarray(tg["bias_drift"]) * (g.t_ref - tr["t_mid"])
    for i, a in enumerate("xyz"):
        out[f"gyro_bias_{a}"] = (g.bias[i], g.u_bias[i], bt[i])
    return out, r.warnings


def _run(case: str, sim_kw: dict, n_seeds: int, seed0: int, note: str, warn: str | None = None
         ) -> list[CoverageRow]:
    vals: dict[str, list] = {}
    warned = []
    for s in range(seed0, seed0 + n_seeds):
        try:
            out, w = _one(s, sim_kw)
        except Exception:  # noqa: BLE001 - a refused session quotes nothing: a miss for every number
            out, w = {}, ()
        warned.append(bool(warn) and has_warning(w, warn))
        for k, v in out.items():
            vals.setdefault(k, []).append(v)
    rows = []
    for k, v in vals.items():
        e, u, t = (np.array(x, float) for x in zip(*v))
        rows.append(coverage_row(JOB, case, k, e, u, t, warned=warned if warn else None,
                                 expect="warn" if warn else "cover", note=note))
    if warn and not rows:
        rows.append(CoverageRow(JOB, case, "warning", n_seeds, math.nan, math.nan, float(np.mean(warned)), "warn",
                                note))
    return rows


def run_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """30 poses, white MEMS noise: every number must cover."""
    return _run("white", {}, n_seeds, seed0, "30 poses, white noise")


def run_bias_drift(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Gyro bias drifting linearly during the session (modelled): must cover."""
    return _run("bias-drift", {"gyro_bias_drift": (2e-5, -2e-5, 2e-5)}, n_seeds, seed0,
                "gyro bias drifting 2e-5 rad/s per s")


def run_coloured(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """AR(1) 0.95 gyro noise: ``gyro-residuals-inconsistent`` must fire."""
    return _run("coloured-gyro", {"gyro_ar1": 0.95}, n_seeds, seed0, "AR(1) 0.95 gyro noise",
                warn="gyro-residuals-inconsistent")


def run_unexcited(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """No rotation about Z: ``gyro-axis-unexcited`` must fire."""
    return _run("axis-unexcited", {"exclude_axis": 2}, n_seeds, seed0, "no rotation about Z",
                warn="gyro-axis-unexcited")


for _f, _ci in ((run_white, 8), (run_bias_drift, 4), (run_coloured, 3), (run_unexcited, 3)):
    _f.full_seeds = 200  # type: ignore[attr-defined]
    _f.ci_seeds = _ci  # type: ignore[attr-defined]

SCENARIOS = {"white": run_white, "bias-drift": run_bias_drift, "coloured-gyro": run_coloured,
             "axis-unexcited": run_unexcited}
