"""Monte-Carlo coverage of ``senscal imu calibrate --rate-table`` (issue 27); merged into senscal.validation.imu.

Each seed simulates the multi-pose session of :mod:`senscal.validation.imu` followed by rate-table runs
(:class:`senscal.simulate.imu_table.TableSpec`: each body axis up on the table, +-1 rad/s for 20 s; the
table's true rate off its stated one by a draw with the stated u, 5e-5 relative, common to all segments; each
mount tilted by a draw with the stated axis u, 0.05 deg per direction), calibrates it with the stated table
and checks the gyro scales, misalignment angles and bias and the accelerometer's parameters against the truth
at k = 2.

Scenarios: ``rate-table`` (three axes on the table: must cover); ``rate-table-single-axis`` (only Z on the
table, X and Y from the poses alone: must cover); ``rate-table-wrong-rate`` (the table turns 0.1 % slower
than it states, 20 times the stated u: ``rate-table-inconsistent`` must fire); ``rate-table-tilted-mount``
(the IMU sits 0.3 deg tilted on the table, stated as exactly aligned: ``rate-table-inconsistent`` must fire);
``rate-table-temperature`` (the ``temperature-gyro-scale`` warm-up 15 -> 45 degC over the poses with gyro scale
and bias tempcos, then the table runs while the IMU cools linearly to 25 degC, calibrated with the temperature
channel: the segments read through the poses' temperature model; every number, the temperature coefficients
too, must cover at the reference temperature, and ``rate-table-inconsistent`` must stay at its false-alarm
rate).
"""

from __future__ import annotations

import math

import numpy as np

from senscal.diagnostics import has_warning
from senscal.validation import CoverageRow, coverage_row

__all__ = ["SCENARIOS", "run_rate_table", "run_single_axis", "run_wrong_rate", "run_tilted_mount", "run_temperature"]

JOB = "imu"
WARNING = "rate-table-inconsistent"
#: The stated (and drawn) standard u of each mount's axis direction, rad.
U_AXIS = math.radians(0.05)


def _one(seed: int, spec_kw: dict) -> tuple[dict, tuple]:
    from senscal.imu import ACCEL_NAMES, GYRO_ANGLES, calibrate_imu
    from senscal.simulate.imu import simulate_imu
    from senscal.simulate.imu_table import TableSpec, rate_table_of

    rec, tr = simulate_imu(seed=seed, rate_table=TableSpec(**spec_kw))
    r = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s",
                      rate_table=rate_table_of(tr))
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


def _one_temperature(seed: int, spec_kw: dict) -> tuple[dict, tuple]:
    """The warm-up session with a rate table, calibrated with the temperature channel; scored at the reference."""
    from senscal.imu import calibrate_imu
    from senscal.simulate.imu import simulate_imu
    from senscal.simulate.imu_table import TableSpec, rate_table_of
    from senscal.validation.imu import TEMPERATURE_SCALE, score

    rec, tr = simulate_imu(seed=seed, rate_table=TableSpec(**spec_kw), **TEMPERATURE_SCALE)
    r = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s",
                      temperature=rec.data(["temp"])[0], rate_table=rate_table_of(tr))
    return score(r, tr), r.warnings


def _run(case: str, spec_kw: dict, n_seeds: int, seed0: int, note: str, warn: bool = False,
         one=None) -> list[CoverageRow]:
    vals: dict[str, list] = {}
    warned = []
    for s in range(seed0, seed0 + n_seeds):
        try:
            out, w = (one or _one)(s, spec_kw)
        except Exception:  # noqa: BLE001 - a refused session quotes nothing: a miss for every number
            out, w = {}, ()
        warned.append(has_warning(w, WARNING))
        for k, v in out.items():
            vals.setdefault(k, []).append(v)
    rows = []
    for k, v in vals.items():
        e, u, t = (np.array(x, float) for x in zip(*v))
        # The warned column of a covering case is its false-alarm rate (the test's level is 0.1 %).
        rows.append(coverage_row(JOB, case, k, e, u, t, warned=warned, expect="warn" if warn else "cover",
                                 note=note))
    if warn and not rows:
        rows.append(CoverageRow(JOB, case, "warning", n_seeds, math.nan, math.nan, float(np.mean(warned)), "warn",
                                note))
    return rows


def run_rate_table(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Three axes on the table, +-1 rad/s: every number must cover."""
    return _run("rate-table", {"u_axis": U_AXIS}, n_seeds, seed0, "30 poses + table +-1 rad/s about x, y, z")


def run_single_axis(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Only Z on the table: must cover (X, Y from the poses)."""
    return _run("rate-table-single-axis", {"axes": ("z",), "u_axis": U_AXIS}, n_seeds, seed0,
                "30 poses + table +-1 rad/s about z")


def run_wrong_rate(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The table states a rate 0.1 % off (20 u): ``rate-table-inconsistent`` must fire."""
    return _run("rate-table-wrong-rate", {"rate_error_rel": 1e-3}, n_seeds, seed0, "stated rate 0.1 % high",
                warn=True)


def run_tilted_mount(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The IMU tilted 0.3 deg on the table, stated aligned: ``rate-table-inconsistent`` must fire."""
    return _run("rate-table-tilted-mount", {"mount_tilt": math.radians(0.3)}, n_seeds, seed0,
                "axis tilted 0.3 deg, u_axis 0 stated", warn=True)


#: The table runs while the IMU cools from the warm-up's end to this temperature, degC.
TABLE_TEMPERATURE_END = 25.0


def run_temperature(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Warm-up over the poses, the table cooling to 25 degC, gyro scale and bias tempcos: must cover."""
    return _run("rate-table-temperature", {"u_axis": U_AXIS, "temperature_end": TABLE_TEMPERATURE_END}, n_seeds,
                seed0, "15->45 degC over the poses, table cooling to 25 degC; gyro scale/bias tempcos",
                one=_one_temperature)


for _f in (run_rate_table, run_single_axis, run_wrong_rate, run_tilted_mount, run_temperature):
    _f.full_seeds = 200  # type: ignore[attr-defined]
    _f.ci_seeds = 2  # type: ignore[attr-defined]

SCENARIOS = {"rate-table": run_rate_table, "rate-table-single-axis": run_single_axis,
             "rate-table-wrong-rate": run_wrong_rate, "rate-table-tilted-mount": run_tilted_mount,
             "rate-table-temperature": run_temperature}
