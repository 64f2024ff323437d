"""Monte-Carlo coverage of ``senscal gfimu``: the Kalman rate band and the constant-error estimates.

Every scenario runs :func:`senscal.gfimu.angular_velocity` as the command
line does by default (quadratic observation with the nine constant-error
states, noise estimated from the readings) on :func:`senscal.simulate.gfimu.
simulate_gfimu` records and checks the k = 2 band pointwise: per seed one
sample time drawn uniformly over the record (independently per axis), so
that the coverage is over time and seeds and the seeds stay independent
(the errors of neighbouring samples are strongly correlated; pooling many
times per seed would make the Wilson interval falsely narrow).

Scenarios
---------
paper-white
    The paper's simulation: 30 deg / 2 Hz about z, array 0.1 m off the
    rotation centre, 10 kHz, 10 s, 1e-4 g biases (random sign), 1e-3 g noise.
three-axis-white
    Roll/pitch/yaw 10/15/30 deg at 1.3/0.7/2 Hz with 2 m/s^2 linear
    vibration, 1 kHz, 10 s, same sensor errors.
three-axis-smooth
    The same with the offline RTS smoother (``smooth=True``).
paper-rest
    The paper's motion after a 2 s rest, 2 kHz, ``rest=(0, 2)``: the rate
    band and the nine constant errors measured on the rest segment.
paper-plain
    The paper's plain filter (``plain=True``): its white-noise band misses
    the biases; expects the ``constant-errors-ignored`` warning.
paper-mounting, three-axis-mounting
    0.5 mm position and 0.5 deg direction errors per channel (the solver
    sees the nominal layout), 1 kHz, 20 s: expects ``filter-gated`` or
    ``innovations-inconsistent``.
three-axis-scale-0.05%, three-axis-scale-0.1%, paper-scale-0.05%
    Every channel's scale factor 0.05 % (0.1 %) off, random sign, which the
    layout does not know (``simulate_gfimu(scale_error=...)``); the paper's
    motion at 2 kHz. The rate band covers far less than 95 %: expects
    ``scale-factor-mismatch`` (the score test of per-channel gains on the
    filter's innovations, :func:`senscal.gfimu.scale_factor_test`).
"""

from __future__ import annotations

import math

import numpy as np

from senscal.gfimu import UNKNOWNS, angular_velocity, paper_layout, solve_kinematics
from senscal.simulate.gfimu import G0, simulate_gfimu
from senscal.validation import CoverageRow, coverage_row

__all__ = ["SCENARIOS"]

JOB = "gfimu"
_AXES = ("wx", "wy", "wz")
_MISMATCH = ("filter-gated", "innovations-inconsistent")
_SCALE = ("scale-factor-mismatch",)


def _has(warnings, names) -> bool:
    return any(w.split(":", 1)[0] in names for w in warnings)


def _offset_truth(layout, bias: np.ndarray) -> np.ndarray:
    """The nine constant errors of alpha and W that channel biases put into the solve."""
    kin = solve_kinematics(np.zeros((layout.n_channels, 1)), layout)
    return kin.sensitivity[3:12] @ bias


def _bias_white(n_seeds: int, seed0: int, case: str, sim: dict, *, rest=None, plain: bool = False,
                smooth: bool = False, expect: str = "cover", warn_names=(), note: str = "",
                scale_error: float = 0.0) -> list[CoverageRow]:
    """White noise and constant biases on one motion: the ideal readings are simulated once.

    Per seed the biases (random sign, ``bias_g``) and the white noise are
    drawn exactly as :func:`simulate_gfimu` draws them; the motion, and so
    the ideal readings and the truth, are the same for every seed. With
    ``scale_error`` every channel's gain is off by that fraction, random sign
    (drawn per seed after the noise, as the simulator does).
    """
    layout = paper_layout(0.04)
    base, truth, info = simulate_gfimu(bias_g=0.0, noise_g=0.0, seed=0, **sim)
    y0 = base.data(list(layout.names))
    t = base.time
    w_true = truth.data(list(_AXES))
    bias_g, noise_g = 1e-4, 1e-3
    est_w, u_w, tr_w = ([[] for _ in range(3)] for _ in range(3))
    est_c, u_c, tr_c, warned = [], [], [], []
    est_f, u_f, tr_f = [], [], []
    for s in range(seed0, seed0 + n_seeds):
        rng = np.random.default_rng(s)
        bias = bias_g * G0 * rng.choice([-1.0, 1.0], size=layout.n_channels)
        y = y0 + bias[:, None] + rng.normal(0.0, noise_g * G0, y0.shape)
        if scale_error > 0:
            y += y0 * (scale_error * rng.choice([-1.0, 1.0], size=layout.n_channels))[:, None]
        est = angular_velocity(y, t, layout, rest=rest, plain=plain, smooth=smooth)
        warned.append(_has(est.warnings, warn_names) if warn_names else False)
        for i in range(3):
            k = int(rng.integers(t.size))
            est_w[i].append(est.omega["kalman"][i, k])
            u_w[i].append(est.u_omega[i, k])
            tr_w[i].append(w_true[i, k])
        c_true = _offset_truth(layout, bias)
        if rest is not None:
            j = int(rng.integers(9))
            est_c.append(est.rest.offsets[j])
            u_c.append(est.rest.u_offsets[j])
            tr_c.append(c_true[j])
        if est.filter.offsets is not None:
            j = int(rng.integers(9))
            est_f.append(est.filter.offsets[j])
            u_f.append(est.filter.u_offsets[j])
            tr_f.append(c_true[j])
    wflag = warned if warn_names else None
    rows = [coverage_row(JOB, case, f"{ax} (pointwise band)", est_w[i], u_w[i], tr_w[i], warned=wflag,
                         expect=expect, note=note) for i, ax in enumerate(_AXES)]
    if rest is not None:
        rows.append(coverage_row(JOB, case, "rest offsets (alpha, W; one of 9 per seed)", est_c, u_c, tr_c,
                                 note="constant errors of " + ", ".join(UNKNOWNS[3:]) + " on the rest segment"))
    if est_f and not smooth:
        rows.append(coverage_row(JOB, case, "filter offsets at the end (one of 9 per seed)", est_f, u_f, tr_f,
                                 warned=wflag, expect=expect,
                                 note="constant errors of alpha and W estimated by the filter"))
    return rows


def run_paper_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The paper's simulation, default filter (constant-error states).  400 seeds at ~0.5 s each."""
    return _bias_white(n_seeds, seed0, "paper-white", dict(paper=True),
                       note="paper set-up, 10 kHz x 10 s, 1e-4 g biases, 1e-3 g noise")


def run_three_axis_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Three-axis motion with linear vibration, default filter."""
    return _bias_white(n_seeds, seed0, "three-axis-white", dict(paper=False),
                       note="roll/pitch/yaw + 2 m/s^2 linear vibration, 1 kHz x 10 s")


def run_three_axis_smooth(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Three-axis motion, offline RTS smoother (``--smooth``) with the constant-error states."""
    return _bias_white(n_seeds, seed0, "three-axis-smooth", dict(paper=False), smooth=True,
                       note="as three-axis-white, --smooth")


def run_paper_rest(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The paper's motion after a 2 s rest marked as ``rest=(0, 2)`` (2 kHz to keep the run short)."""
    return _bias_white(n_seeds, seed0, "paper-rest", dict(paper=True, fs=2000.0, rest_s=2.0), rest=(0.0, 2.0),
                       note="2 s rest then the paper's motion, 2 kHz; constant errors from the rest segment")


def run_paper_plain(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The paper's plain filter: its band leaves the biases out, so the warning must name it."""
    return _bias_white(n_seeds, seed0, "paper-plain", dict(paper=True, fs=2000.0), plain=True, expect="warn",
                       warn_names=("constant-errors-ignored",),
                       note="plain filter (--plain), biases not in u, 2 kHz x 10 s")


def _mounting(n_seeds: int, seed0: int, case: str, paper: bool) -> list[CoverageRow]:
    layout = paper_layout(0.04)
    est_w, u_w, tr_w = ([[] for _ in range(3)] for _ in range(3))
    warned = []
    for s in range(seed0, seed0 + n_seeds):
        rec, truth, _ = simulate_gfimu(paper=paper, fs=1000.0, duration=20.0, position_error_m=5e-4,
                                       direction_error_rad=math.radians(0.5), seed=s)
        est = angular_velocity(rec.data(list(layout.names)), rec.time, layout)
        warned.append(_has(est.warnings, _MISMATCH))
        w_true = truth.data(list(_AXES))
        rng = np.random.default_rng(10_000 + s)
        for i in range(3):
            k = int(rng.integers(rec.time.size))
            est_w[i].append(est.omega["kalman"][i, k])
            u_w[i].append(est.u_omega[i, k])
            tr_w[i].append(w_true[i, k])
    return [coverage_row(JOB, case, f"{ax} (pointwise band)", est_w[i], u_w[i], tr_w[i], warned=warned,
                         expect="warn", note="0.5 mm / 0.5 deg mounting errors, 1 kHz x 20 s")
            for i, ax in enumerate(_AXES)]


def run_paper_mounting(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Paper motion (30 deg / 2 Hz) with mounting errors: must warn."""
    return _mounting(n_seeds, seed0, "paper-mounting", True)


def run_three_axis_mounting(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Three-axis motion with mounting errors: must warn."""
    return _mounting(n_seeds, seed0, "three-axis-mounting", False)


def run_three_axis_scale_05(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Three-axis motion, every channel's gain 0.05 % off (random sign): must name it."""
    return _bias_white(n_seeds, seed0, "three-axis-scale-0.05%", dict(paper=False), scale_error=5e-4,
                       expect="warn", warn_names=_SCALE, note="scale factors 0.05 % off, random sign, 1 kHz x 10 s")


def run_three_axis_scale_10(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Three-axis motion, every channel's gain 0.1 % off (random sign): must name it."""
    return _bias_white(n_seeds, seed0, "three-axis-scale-0.1%", dict(paper=False), scale_error=1e-3,
                       expect="warn", warn_names=_SCALE, note="scale factors 0.1 % off, random sign, 1 kHz x 10 s")


def run_paper_scale_05(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The paper's motion (2 kHz), every channel's gain 0.05 % off: must name it."""
    return _bias_white(n_seeds, seed0, "paper-scale-0.05%", dict(paper=True, fs=2000.0), scale_error=5e-4,
                       expect="warn", warn_names=_SCALE, note="paper motion, scale factors 0.05 % off, 2 kHz x 10 s")


for _f in (run_paper_white, run_three_axis_white, run_three_axis_smooth, run_paper_rest, run_paper_plain,
           run_paper_mounting, run_three_axis_mounting, run_three_axis_scale_05, run_three_axis_scale_10,
           run_paper_scale_05):
    _f.full_seeds = 400

SCENARIOS = {
    "paper-white": run_paper_white,
    "three-axis-white": run_three_axis_white,
    "three-axis-smooth": run_three_axis_smooth,
    "paper-rest": run_paper_rest,
    "paper-plain": run_paper_plain,
    "paper-mounting": run_paper_mounting,
    "three-axis-mounting": run_three_axis_mounting,
    "three-axis-scale-0.05%": run_three_axis_scale_05,
    "three-axis-scale-0.1%": run_three_axis_scale_10,
    "paper-scale-0.05%": run_paper_scale_05,
}
