"""Angular velocity from an accelerometer array: the whole pipeline.

References
----------
.. [1] Wang W., Dai Y., Chen H., Wang P., "Application of Kalman filter to
   calculate angular velocity of complicated vibration by full acceleration
   sensor", China Measurement & Test, 2017(5) (seed 001); METHODS.md 2.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import InputError, TooFewSamplesError
from senscal.gfimu.filter import OBSERVATIONS, RateFilterResult, channel_covariance, kalman_rate
from senscal.gfimu.layout import KinematicSolution, Layout, solve_kinematics, square_map
from senscal.gfimu.methods import differential_rate, estimate_noise_std, integration_rate, sqrt_rate

__all__ = ["METHODS", "RateEstimate", "ErrorStatistics", "angular_velocity", "error_statistics"]

#: Methods in the order the paper presents them.
METHODS = ("integration", "sqrt", "differential", "kalman")


@dataclass(frozen=True)
class RateEstimate(ResultMixin):
    """Angular velocity of a rigid body from its accelerometer array.

    Attributes
    ----------
    t : ndarray, shape (T,)
        Time, s.
    omega : dict of str to ndarray (3, T)
        Angular velocity per method, rad/s (NaN where the differential
        method rejected a sample).
    u_omega : ndarray, shape (3, T) or None
        Standard uncertainty of the Kalman estimate (white noise only), rad/s.
    kinematics : KinematicSolution
        Specific force, angular acceleration and quadratic terms per sample.
    noise_std : ndarray, shape (M,)
        White-noise standard deviation of each channel used (m/s^2).
    condition_number : float
        Scale-free condition number of the layout.
    filter : RateFilterResult or None
        Diagnostics of the Kalman filter.
    differential_rejected : int
        Samples x axes the differential method rejected as ill-conditioned.
    """

    t: np.ndarray = field(repr=False)
    omega: dict = field(repr=False)
    u_omega: np.ndarray | None = field(repr=False)
    kinematics: KinematicSolution = field(repr=False)
    noise_std: np.ndarray
    condition_number: float
    filter: RateFilterResult | None
    differential_rejected: int


def angular_velocity(readings: np.ndarray, t: np.ndarray, layout: Layout, *,
                     methods: Sequence[str] = ("kalman",), observation: str = "quadratic",
                     initial=(0.0, 0.0, 0.0), noise_std=None, lag: int = 1,
                     gate_probability: float = 1e-4, bias_std=None, smooth: bool = False) -> RateEstimate:
    """Solve the array's kinematics and estimate ``w`` by the chosen methods.

    Parameters
    ----------
    readings : ndarray, shape (M, T)
        Accelerometer readings in m/s^2, rows in ``layout.names`` order.
    t : ndarray, shape (T,)
        Time, s (strictly increasing).
    layout : Layout
        Positions (m) and directions of the channels.
    methods : sequence of str
        Any of ``"integration"``, ``"sqrt"``, ``"differential"``, ``"kalman"``.
    observation : {"quadratic", "sqrt", "differential"}
        Observation of the Kalman filter (see :func:`kalman_rate`).
    initial : sequence of 3 floats or None
        Angular velocity at ``t[0]``, rad/s (default: at rest).  ``None``
        lets the linear Kalman filters start from their first observations.
    noise_std : float or ndarray (M,), optional
        White-noise standard deviation of the channels, m/s^2; estimated
        from the second differences of the readings when omitted.
    lag : int
        Span of the differential method in samples (1: the paper's).
    gate_probability : float
        False-rejection probability of the filter's innovation gate.
    bias_std : float or ndarray (M,), optional
        Standard uncertainty of the channels' constant errors, m/s^2; the
        quadratic Kalman filter then estimates the constant errors they put
        into the kinematics (see :func:`kalman_rate`).
    smooth : bool
        Offline: the Kalman estimate is the fixed-interval (RTS) smoother's
        (uses the whole record; the default filter is causal).

    Returns
    -------
    RateEstimate

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), sections 1.3-3.
    """
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise InputError(f"unknown method {', '.join(bad) or '(none)'}; choose from {', '.join(METHODS)}")
    if observation not in OBSERVATIONS:
        raise InputError(f"observation must be one of {', '.join(OBSERVATIONS)}, got {observation!r}")
    t = np.asarray(t, float)
    y = np.asarray(readings, float)
    if y.ndim != 2 or y.shape[1] != t.size:
        raise InputError(f"readings must have shape (M, T) matching t of {t.size} samples, got {y.shape}")
    if t.size < 8:
        raise TooFewSamplesError(f"angular velocity from the array needs at least 8 samples, got {t.size}")
    kin = solve_kinematics(y, layout)
    sig = estimate_noise_std(y) if noise_std is None else np.broadcast_to(np.asarray(noise_std, float), (y.shape[0],))
    if not np.all(np.isfinite(sig)) or np.any(sig < 0):
        raise InputError("noise_std must be non-negative numbers (m/s^2)")
    # A noise-free record still needs a non-singular observation covariance.
    sig = np.maximum(sig, 1e-12)
    w0 = None if initial is None else np.asarray(initial, float).reshape(3)
    out: dict[str, np.ndarray] = {}
    alpha, squares = kin.angular_acceleration, kin.squares
    w_int = integration_rate(alpha, t, np.zeros(3) if w0 is None else w0)
    if "integration" in methods:
        out["integration"] = w_int
    if "sqrt" in methods:
        out["sqrt"] = sqrt_rate(squares, w_int)
    n_rej = 0
    if "differential" in methods:
        C = channel_covariance(kin, sig)
        S = square_map()
        s_sq = np.sqrt(np.diag(S @ C[6:9, 6:9] @ S.T))
        w_d, _, rej = differential_rate(squares, alpha, t, lag=lag, squares_std=s_sq)
        out["differential"] = w_d
        n_rej = int(rej.sum())
    filt = None
    u_om = None
    if "kalman" in methods:
        filt = kalman_rate(kin, t, sig, observation=observation, initial=w0, lag=lag,
                           gate_probability=gate_probability, bias_std=bias_std, smooth=smooth)
        out["kalman"] = filt.omega
        u_om = filt.u_omega
    ordered = {m: out[m] for m in METHODS if m in out}
    return RateEstimate(t=t, omega=ordered, u_omega=u_om, kinematics=kin, noise_std=np.asarray(sig),
                        condition_number=kin.condition_number, filter=filt, differential_rejected=n_rej)


@dataclass(frozen=True)
class ErrorStatistics(ResultMixin):
    """Error of one method against the truth, per axis (the paper's Table 2).

    Attributes
    ----------
    method : str
    max_abs_error : ndarray, shape (3,)
        Largest absolute error per axis over the valid samples, rad/s.
    std_error : ndarray, shape (3,)
        Standard deviation of the error per axis, rad/s.
    mean_error : ndarray, shape (3,)
        Mean error per axis, rad/s.
    n_valid : ndarray, shape (3,)
        Samples compared per axis (rejected samples excluded).
    """

    method: str
    max_abs_error: np.ndarray
    std_error: np.ndarray
    mean_error: np.ndarray
    n_valid: np.ndarray

    def axis(self, i: int) -> dict:
        return {"max_abs_error": float(self.max_abs_error[i]), "std_error": float(self.std_error[i]),
                "mean_error": float(self.mean_error[i]), "n_valid": int(self.n_valid[i])}


def error_statistics(omega: dict, truth: np.ndarray, *, skip: int = 0) -> dict[str, ErrorStatistics]:
    """Max absolute error and standard deviation of each method against the truth.

    Parameters
    ----------
    omega : dict of str to ndarray (3, T)
        Estimates per method, rad/s (NaN samples are left out).
    truth : ndarray, shape (3, T)
        True angular velocity, rad/s.
    skip : int
        Leading samples left out (filter start-up), default none.

    Returns
    -------
    dict of str to ErrorStatistics

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), Table 2.
    """
    truth = np.asarray(truth, float)
    res = {}
    for name, est in omega.items():
        est = np.asarray(est, float)
        if est.shape != truth.shape:
            raise InputError(f"truth has shape {truth.shape} but the {name} estimate {est.shape}; "
                             "the truth must share the recording's time base")
        e = (est - truth)[:, skip:]
        ok = np.isfinite(e)
        n = ok.sum(axis=1)
        with np.errstate(invalid="ignore"):
            ez = np.where(ok, e, 0.0)
            mean = np.where(n > 0, ez.sum(axis=1) / np.maximum(n, 1), np.nan)
            var = np.where(n > 1, (np.where(ok, e - mean[:, None], 0.0) ** 2).sum(axis=1) / np.maximum(n - 1, 1), np.nan)
            mx = np.where(n > 0, np.abs(ez).max(axis=1), np.nan)
        res[name] = ErrorStatistics(method=name, max_abs_error=mx, std_error=np.sqrt(var), mean_error=mean, n_valid=n)
    return res
