"""Monte-Carlo coverage of ``senscal imu calibrate`` (issue 27).

Each seed simulates a multi-pose session (:func:`senscal.simulate.imu.simulate_imu`: 20 s still start,
30 poses of 3 s joined by 1.5 s rotations about random axes, 100 Hz, MEMS noise 0.02 m/s^2 and
0.002 rad/s per sample), calibrates it and checks every quoted number against the truth at k = 2:
accelerometer gains, angles and offsets, gyro scales (signed row norms of ``M_g``), the six gyro
misalignment angles and the gyro bias at the reported time.

Scenarios: ``white``; ``bias-drift`` (gyro bias drifting 2e-5 rad/s per s on each axis: modelled, must
cover); ``coloured-gyro`` (AR(1) 0.95 gyro noise: the still samples' lag-one correlation names it,
``gyro-noise-coloured`` must fire; the u then use the long-run variance); ``axis-unexcited`` (no rotation about Z: ``gyro-axis-unexcited``
must fire); ``temperature`` (a 15 -> 45 degC warm-up with accelerometer bias and scale and gyro bias
temperature coefficients, calibrated with the temperature channel: every number and the linear temperature
coefficients must cover, at the reference temperature the job states); ``temperature-small-swing`` (25 -> 27
degC: ``temperature-swing-small`` must fire); ``g-sensitivity`` (a gyro reading 2e-4 rad/s per m/s^2,
calibrated with ``g_sensitivity``: must cover, the nine G elements too); ``g-sensitivity-unmodelled`` (the
same, calibrated without: ``gyro-g-sensitivity`` must fire); ``yaw-in-pose`` (three poses hold a 90 deg turn
about the vertical between two 3 s still parts: the accelerometer sees one pose, the gyro check splits it; must
cover); ``yaw-in-pose-unsplit`` (the same with 0.6 s still parts, too short to keep: ``pose-rotation-unsplit``
must fire).
"""

from __future__ import annotations

import math

import numpy as np

from senscal.diagnostics import has_warning
from senscal.validation import CoverageRow, coverage_row

__all__ = ["SCENARIOS", "MEMS", "thirty_poses_mems", "run_mems", "run_white", "run_bias_drift", "run_coloured", "run_unexcited", "run_temperature",
           "run_temperature_scale", "run_small_swing", "run_g_sensitivity", "run_g_unmodelled", "truth_at_reference",
           "run_yaw", "run_yaw_unsplit", "YAW"]

JOB = "imu"


#: Departures' settings (shared by the scenarios and the tests).
TEMPERATURE = {"temperature": (15.0, 45.0), "accel_bias_tc": (2e-3, -1.5e-3, 1e-3),
               "accel_scale_tc": (1e-4, -8e-5, 5e-5), "gyro_bias_tc": (2e-4, -1e-4, 1.5e-4)}
#: The warm-up with the gyro's scale changing too (MEMS gyros: 0.01-0.05 % per K).
TEMPERATURE_SCALE = {**TEMPERATURE, "gyro_scale_tc": (3e-4, -2e-4, 1e-4)}
G_SENSITIVITY = {"gyro_g_sensitivity": ((2e-4, -1e-4, 5e-5), (-5e-5, 2e-4, 1e-4), (1e-4, 5e-5, -2e-4))}


def truth_at_reference(tr: dict, temp_ref: float | None) -> tuple[dict, np.ndarray, dict]:
    """Accelerometer truth, gyro bias offset and temperature coefficients at the job's reference temperature.

    The simulator's accelerometer is ``(1 + s dTn) (Ma f + Ba) + c dTn`` about its nominal temperature; about
    ``T_ref`` (``D = T_ref - T_nominal``) the same is ``(1 + s' dT) (Ma' f + Ba') + c' dT`` with
    ``Ma' = (1 + s D) Ma`` (gains scale, angles stay), ``Ba' = (1 + s D) Ba + c D``, ``s' = s / (1 + s D)``,
    ``c' = c (1 - s' D)``; the gyro bias shifts by ``g D``.  The gyro's rows scale alike: ``(1 + s_g dTn) Mg =
    (1 + s_g' dT) Mg'`` with ``Mg' = (1 + s_g D) Mg`` (scales ``(1 + s_g D)`` times, angles stay) and
    ``s_g' = s_g / (1 + s_g D)``: returned as ``tc["gyro_scale_factor"]`` (``1 + s_g D``) and
    ``tc["gyro_scale_tc"]``.
    """
    acc = dict(tr["accelerometer"])
    te = tr.get("temperature")
    if te is None or temp_ref is None:
        return acc, np.zeros(3), {}
    d = temp_ref - te["nominal"]
    s, c, gb = (np.asarray(te[k], float) for k in ("accel_scale_tc", "accel_bias_tc", "gyro_bias_tc"))
    sg = np.asarray(te.get("gyro_scale_tc", (0.0, 0.0, 0.0)), float)
    for i, a in enumerate("xyz"):
        acc[f"K{a}"] = acc[f"K{a}"] * (1 + s[i] * d)
        acc[f"B{a}"] = acc[f"B{a}"] * (1 + s[i] * d) + c[i] * d
    sp = s / (1 + s * d)
    return acc, gb * d, {"accel_scale_tc": sp, "accel_bias_tc": c * (1 - sp * d), "gyro_bias_tc": gb,
                         "gyro_scale_tc": sg / (1 + sg * d), "gyro_scale_factor": 1 + sg * d}


def _one(seed: int, sim_kw: dict, cal_kw: dict | None = None):
    from senscal.imu import calibrate_imu
    from senscal.simulate.imu import simulate_imu

    cal_kw = dict(cal_kw or {})
    rec, tr = simulate_imu(seed=seed, **sim_kw)
    temp = rec.data(["temp"])[0] if cal_kw.pop("temperature", False) else None
    r = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s",
                      temperature=temp, **cal_kw)
    return score(r, tr), r.warnings


def score(r, tr: dict) -> dict[str, tuple[float, float, float]]:
    """Every number a calibration quotes, as ``name -> (estimate, u, truth)`` (truth at the job's reference).

    Parameters
    ----------
    r : senscal.imu.ImuResult
    tr : dict
        The simulator's truth (:func:`senscal.simulate.imu.simulate_imu`).
    """
    from senscal.imu import ACCEL_NAMES, GYRO_ANGLES

    g, tg = r.gyroscope, tr["gyroscope"]
    te = r.temperature
    acc, db, tc = truth_at_reference(tr, te.reference if te is not None else None)
    out = {}
    ua = np.sqrt(np.clip(np.diag(r.accel_covariance), 0, None))
    for i, n in enumerate(ACCEL_NAMES):
        out[f"accel_{n}"] = (r.accel_values[i], ua[i], acc[n])
    gsf = tc.get("gyro_scale_factor", np.ones(3))
    for i, a in enumerate("xyz"):
        out[f"gyro_scale_{a}"] = (g.scale[i], g.u_scale[i], tg[f"scale_{a}"] * gsf[i])
    for i, n in enumerate(GYRO_ANGLES):
        out[f"gyro_angle_{n}"] = (g.angles[i], g.u_angles[i], tg[f"angle_{n}"])
    # The bias is the reading at zero input (zero rate, zero specific force): with an unmodelled G the job's
    # bias absorbs G f over the poses and misses it unless the departure is named.
    bt = np.asarray(tg["bias"]) + np.asarray(tg["bias_drift"]) * (g.t_ref - tr["t_mid"]) + db
    for i, a in enumerate("xyz"):
        out[f"gyro_bias_{a}"] = (g.bias[i], g.u_bias[i], bt[i])
    if g.g_sensitivity is not None and tr.get("g_sensitivity") is not None:
        gt = np.asarray(tr["g_sensitivity"], float)
        for i in range(3):
            for j in range(3):
                out[f"gyro_G_{'xyz'[i]}{'xyz'[j]}"] = (g.g_sensitivity[i, j], g.u_g_sensitivity[i, j], gt[i, j])
    if te is not None and tc:
        for key, est, u, deg in (("accel_bias_tc", te.accel_bias, te.u_accel_bias, te.degree_accel),
                                 ("accel_scale_tc", te.accel_scale, te.u_accel_scale, te.degree_accel),
                                 ("gyro_bias_tc", te.gyro_bias, te.u_gyro_bias, te.degree_gyro),
                                 ("gyro_scale_tc", te.gyro_scale, te.u_gyro_scale, te.degree_gyro_scale)):
            if not np.any(tc[key]):
                continue  # no such dependence in the truth: nothing to cover (the held-out choice may add a term)
            for i, a in enumerate("xyz"):
                # The linear coefficient; a seed whose held-out choice dropped the term quotes none: a miss.
                out[f"{key}_{a}"] = (est[0, i], u[0, i], tc[key][i]) if deg else (math.nan, math.nan, tc[key][i])
    return out


def _collect(sim_kw: dict, n_seeds: int, seed0: int, warn: str | None, cal_kw: dict | None):
    vals: dict[str, list] = {}
    warned, flagged = [], []
    for s in range(seed0, seed0 + n_seeds):
        try:
            out, w = _one(s, sim_kw, cal_kw)
        except Exception:  # noqa: BLE001 - a refused session quotes nothing: a miss for every number
            out, w = {}, ("refused",)
        warned.append(bool(warn) and has_warning(w, warn))
        flagged.append(bool(w))
        for k, v in out.items():
            vals.setdefault(k, []).append(v)
    return vals, warned, flagged


def _run(case: str, sim_kw: dict, n_seeds: int, seed0: int, note: str, warn: str | None = None,
         cal_kw: dict | None = None) -> list[CoverageRow]:
    vals, warned, _ = _collect(sim_kw, n_seeds, seed0, warn, cal_kw)
    rows = []
    for k, v in vals.items():
        e, u, t = (np.array(x, float) for x in zip(*v))
        rows.append(coverage_row(JOB, case, k, e, u, t, warned=warned if warn else None,
                                 expect="warn" if warn else "cover", note=note))
    if warn and not rows:
        rows.append(CoverageRow(JOB, case, "warning", n_seeds, math.nan, math.nan, float(np.mean(warned)), "warn",
                                note))
    return rows


#: A MEMS IMU of the BMI088 class at 100 Hz: gyro 0.014 deg/s/sqrt(Hz), accelerometer 175 ug/sqrt(Hz); per
#: sample ``density * sqrt(fs)`` (the kalibr convention the job's --noise-yaml uses).
MEMS = {"n_poses": 30, "fs": 100.0, "gyro_noise": math.radians(0.014) * 10.0, "accel_noise": 175e-6 * 9.80665 * 10.0}


def thirty_poses_mems(n_seeds: int, seed0: int = 0) -> tuple[list[CoverageRow], np.ndarray]:
    """30 poses at MEMS noise (:data:`MEMS`): coverage rows and each seed's relative gyro-scale u.

    Issue 27 asks for a gyroscope scale u below 0.1 % with 30 poses at MEMS noise; the rows' quantity names
    for the gyro scales carry the largest ``u / scale`` over the seeds the job raised no warning for (a
    session it names, e.g. a rotation about gravity the accelerometer cannot see inside a pose, is not a
    30-pose calibration) and how many those are.

    Returns
    -------
    (rows, rel_u, flagged)
        ``rel_u``: shape (seeds, 3), ``u_scale / |scale|`` per seed and axis (NaN for a refused seed);
        ``flagged``: per seed, did the job name a departure (or refuse).
    """
    vals, _, flagged = _collect(MEMS, n_seeds, seed0, None, None)
    flagged = np.asarray(flagged, bool)
    rel = np.full((n_seeds, 3), math.nan)
    ok = np.flatnonzero([not f for f in flagged]) if vals else np.zeros(0, int)
    for i, a in enumerate("xyz"):
        v = np.array(vals.get(f"gyro_scale_{a}", []), float).reshape(-1, 3)
        if v.shape[0] == n_seeds:
            rel[:, i] = v[:, 1] / np.abs(v[:, 0])
    note = "30 poses, MEMS noise (0.014 deg/s/sqrt(Hz), 175 ug/sqrt(Hz), 100 Hz)"
    rows = []
    for k, v in vals.items():
        e, u, t = (np.array(x, float) for x in zip(*v))
        q = k
        if k.startswith("gyro_scale_"):
            i = "xyz".index(k[-1])
            q = (f"{k} (u/scale max {100 * np.nanmax(rel[ok, i]):.4f} % over {ok.size} unflagged seeds)"
                 if ok.size else k)
        rows.append(coverage_row(JOB, "mems-30-poses", q, e, u, t, note=note))
    return rows, rel, flagged


def run_mems(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """30 poses at MEMS noise: every number covers; the gyro scale rows name the largest relative u."""
    return thirty_poses_mems(n_seeds, seed0)[0]


def run_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """30 poses, white MEMS noise: every number must cover."""
    return _run("white", {}, n_seeds, seed0, "30 poses, white noise")


def run_bias_drift(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Gyro bias drifting linearly during the session (modelled): must cover."""
    return _run("bias-drift", {"gyro_bias_drift": (2e-5, -2e-5, 2e-5)}, n_seeds, seed0,
                "gyro bias drifting 2e-5 rad/s per s")


def run_coloured(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """AR(1) 0.95 gyro noise: ``gyro-noise-coloured`` must fire."""
    return _run("coloured-gyro", {"gyro_ar1": 0.95}, n_seeds, seed0, "AR(1) 0.95 gyro noise",
                warn="gyro-noise-coloured")


def run_unexcited(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """No rotation about Z: ``gyro-axis-unexcited`` must fire."""
    return _run("axis-unexcited", {"exclude_axis": 2}, n_seeds, seed0, "no rotation about Z",
                warn="gyro-axis-unexcited")


def run_temperature(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """15 -> 45 degC warm-up with temperature coefficients, calibrated with the channel: must cover."""
    return _run("temperature", TEMPERATURE, n_seeds, seed0, "15->45 degC warm-up, linear tempcos",
                cal_kw={"temperature": True})


def run_temperature_scale(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The warm-up with the gyro scale changing 1-3e-4 per K too: must cover, the scale coefficients too."""
    return _run("temperature-gyro-scale", TEMPERATURE_SCALE, n_seeds, seed0,
                "15->45 degC warm-up, linear tempcos incl. gyro scale", cal_kw={"temperature": True})


def run_small_swing(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """25 -> 27 degC only: ``temperature-swing-small`` must fire."""
    return _run("temperature-small-swing", {**TEMPERATURE, "temperature": (25.0, 27.0)}, n_seeds, seed0,
                "25->27 degC", warn="temperature-swing-small", cal_kw={"temperature": True})


def run_g_sensitivity(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Gyro g-sensitivity 2e-4 rad/s per m/s^2, fitted: must cover (G too)."""
    return _run("g-sensitivity", G_SENSITIVITY, n_seeds, seed0, "G ~2e-4 rad/s per m/s^2, fitted",
                cal_kw={"g_sensitivity": True})


def run_g_unmodelled(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The same gyro calibrated without ``g_sensitivity``: ``gyro-g-sensitivity`` must fire."""
    return _run("g-sensitivity-unmodelled", G_SENSITIVITY, n_seeds, seed0, "G ~2e-4 rad/s per m/s^2, not fitted",
                warn="gyro-g-sensitivity")


#: Three poses holding a 90 deg turn about the vertical (the accelerometer cannot see it).
YAW = {"yaw_poses": 3, "yaw_deg": 90.0}


def run_yaw(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """A turn about the vertical inside three poses, 3 s still on each side: split by the gyro, must cover."""
    return _run("yaw-in-pose", YAW, n_seeds, seed0, "3 poses hold a 90 deg turn about gravity (split by the gyro)")


def run_yaw_unsplit(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The same turn with 0.6 s still on each side (below --min-pose): ``pose-rotation-unsplit`` must fire."""
    return _run("yaw-in-pose-unsplit", {**YAW, "yaw_hold_s": 0.6}, n_seeds, seed0,
                "3 poses: 0.6 s still, 90 deg turn about gravity, 0.6 s still", warn="pose-rotation-unsplit")


for _f, _ci in ((run_mems, 2), (run_white, 2), (run_yaw, 2), (run_yaw_unsplit, 2), (run_bias_drift, 2), (run_coloured, 2), (run_unexcited, 2),
                (run_temperature, 2), (run_temperature_scale, 2), (run_small_swing, 2), (run_g_sensitivity, 2),
                (run_g_unmodelled, 2)):
    _f.full_seeds = 200  # type: ignore[attr-defined]
    _f.ci_seeds = _ci  # type: ignore[attr-defined]

SCENARIOS = {"mems-30-poses": run_mems, "white": run_white, "bias-drift": run_bias_drift, "coloured-gyro": run_coloured,
             "axis-unexcited": run_unexcited, "temperature": run_temperature,
             "temperature-gyro-scale": run_temperature_scale,
             "temperature-small-swing": run_small_swing, "g-sensitivity": run_g_sensitivity,
             "g-sensitivity-unmodelled": run_g_unmodelled, "yaw-in-pose": run_yaw, "yaw-in-pose-unsplit": run_yaw_unsplit}

from senscal.validation._imu_ratetable import SCENARIOS as _RATE_TABLE  # noqa: E402 - rate-table cases (their own module)

SCENARIOS.update(_RATE_TABLE)
