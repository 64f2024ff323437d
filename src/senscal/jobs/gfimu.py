"""The ``gfimu`` job: angular velocity of a rigid body from an accelerometer array (no gyroscope).

Reads the array's channels, solves the kinematics and estimates the angular
velocity by the chosen methods (integration, square root, differential, the
Kalman filter), optionally against a truth file and integrated into an
attitude.  Writing the estimates (``--out``) and plots stays with the caller:
:meth:`GfimuResult.output_recording` gives what to write.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from senscal._result import to_jsonable
from senscal.errors import InputError
from senscal.jobs._base import JobResult, ReadOptions, given_or_loaded, read_source, source_name

if TYPE_CHECKING:  # the engines load when a job runs, not when the CLI starts
    from senscal.gfimu import AttitudeError, ErrorStatistics, Layout, RateEstimate

__all__ = ["GfimuOptions", "GfimuResult", "gfimu"]

_AXES = ("wx", "wy", "wz")
_QUATERNION = ("qw", "qx", "qy", "qz")


@dataclass(frozen=True)
class GfimuOptions(ReadOptions):
    """Options of :func:`gfimu` (the ``senscal gfimu`` options).

    Attributes
    ----------
    layout : str, Path, senscal.gfimu.Layout or None
        Layout table (CSV ``name,x,y,z,nx,ny,nz`` in m) or a Layout; None:
        the paper's layout with mounting distance ``distance``.
    distance : float or None
        Mounting distance L of the paper's layout, m (None: 0.04).
    method : str
        ``kalman``, ``integration``, ``sqrt``, ``differential`` or ``all``.
    observation : str
        Kalman observation: ``quadratic``, ``sqrt`` or ``differential``.
    initial_omega : tuple of 3 float
        Angular velocity at the first sample, rad/s.
    truth : str, Path or None
        Truth CSV with t, wx, wy, wz (rad/s) (and qw..qz): adds error statistics.
    attitude : bool
        Integrate the angular velocity into a quaternion.
    lag : int
        Span of the differential method, samples (>= 1).
    noise_std : float or None
        Channel white-noise std, m/s^2 (None: estimated).
    bias_std : float or None
        Standard uncertainty of each channel's constant error, m/s^2
        (None: 0.1 unless ``rest`` or ``plain``).
    plain : bool
        The paper's filter without constant-error states.
    rest : tuple (start, end) or None
        Segment (s) where the body is at rest: constant errors measured there.
    differential_max_u : float or None
        Differential method: reject samples whose u exceeds this, rad/s.
    smooth : bool
        The fixed-interval (RTS) smoother instead of the causal filter.
    time_column, fs, names, time_unit, skip_rows
        How the recording is read (:class:`~senscal.jobs._base.ReadOptions`).
    """

    layout: str | Path | Layout | None = None
    distance: float | None = None
    method: str = "kalman"
    observation: str = "quadratic"
    initial_omega: tuple[float, float, float] = (0.0, 0.0, 0.0)
    truth: str | Path | None = None
    attitude: bool = False
    lag: int = 1
    noise_std: float | None = None
    bias_std: float | None = None
    plain: bool = False
    rest: tuple[float, float] | None = None
    differential_max_u: float | None = None
    smooth: bool = False


@dataclass(frozen=True)
class GfimuResult(JobResult):
    """Angular velocity per method with the filter's diagnostics, errors against a truth and attitude.

    Attributes
    ----------
    estimate : senscal.gfimu.RateEstimate
        Rates per method (rad/s, shape (3, T)), kinematics, filter diagnostics.
    source : str
        The recording.
    t : ndarray, shape (T,)
        Time, s.
    sample_rate : float or None
        Hz.
    layout : senscal.gfimu.Layout
    layout_source : str
        The layout file, or ``"paper, L = 0.04 m"``.
    observation : str
    initial_omega : tuple of 3 float
        rad/s.
    bias_std : float or None
        Prior std of the constant errors the filter used, m/s^2 (None with ``rest``).
    differential_max_u : float or None
        rad/s.
    errors : dict of str to senscal.gfimu.ErrorStatistics, or None
        Error of each method against the truth, rad/s, after the Kalman
        filter's start-up (from ``converged_from_s``; the whole record
        without a Kalman estimate).
    errors_transient : dict of str to senscal.gfimu.ErrorStatistics, or None
        The same over the start-up, before ``converged_from_s`` (None when
        there is none): the filter learns its constant errors there.
    converged_from_s : float or None
        Where the converged part starts, s (:func:`senscal.gfimu.convergence_index`:
        the filter's stated u(w) stays within 2x of its median from there on).
    truth_omega : ndarray, shape (3, T), or None
        The truth on the recording's time base, rad/s.
    quaternion : ndarray, shape (4, T), or None
        Attitude (qw, qx, qy, qz) integrated from ``attitude_method``'s rates.
    attitude_method : str or None
    initial_quaternion : tuple of 4 float or None
    attitude_error : senscal.gfimu.AttitudeError or None
        Attitude against the truth's quaternion, deg.
    warnings : tuple of str
    """

    job: ClassVar[str] = "gfimu"

    estimate: RateEstimate
    source: str
    t: np.ndarray = field(repr=False)
    sample_rate: float | None
    layout: Layout
    layout_source: str
    observation: str
    initial_omega: tuple[float, float, float]
    bias_std: float | None = None
    differential_max_u: float | None = None
    errors: dict[str, ErrorStatistics] | None = None
    errors_transient: dict[str, ErrorStatistics] | None = None
    converged_from_s: float | None = None
    truth_omega: np.ndarray | None = field(default=None, repr=False)
    quaternion: np.ndarray | None = field(default=None, repr=False)
    attitude_method: str | None = None
    initial_quaternion: tuple[float, ...] | None = None
    attitude_error: AttitudeError | None = None
    warnings: tuple[str, ...] = ()

    @property
    def omega(self) -> dict[str, np.ndarray]:
        """Angular velocity per method, rad/s, shape (3, T)."""
        return self.estimate.omega

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal gfimu --json`` document (without the output paths the CLI adds)."""
        from senscal.gfimu import UNKNOWNS

        est = self.estimate
        names = list(self.layout.names)
        doc: dict[str, Any] = {
            "file": self.source, "n_samples": int(self.t.size), "sample_rate_hz": self.sample_rate,
            "layout": {"channels": names, "condition_number": est.condition_number, "source": self.layout_source},
            "methods": list(est.omega), "observation": self.observation if "kalman" in est.omega else None,
            "initial_omega": list(self.initial_omega),
            "noise_std_m_s2": dict(zip(names, est.noise_std.tolist())),
            "differential_rejected": est.differential_rejected if "differential" in est.omega else None,
            "differential_max_u_rad_s": self.differential_max_u if "differential" in est.omega else None,
            "noise_scale": est.noise_scale,
        }
        if est.rest is not None:
            r = est.rest
            doc["rest"] = {"span_s": list(r.span), "n_samples": r.n, "spread_ratio": r.spread_ratio,
                           "offsets": _offsets(UNKNOWNS[3:], r.offsets, r.u_offsets)}
        if est.filter is not None:
            f = est.filter
            doc["filter"] = {"observation": f.observation, "n_observed": f.n_observed, "n_dropped": f.n_dropped,
                             "n_gated": f.n_gated, "passes": f.passes, "smoothed": f.smoothed,
                             "constant_error_states": f.offsets is not None,
                             "median_u_omega": dict(zip(_AXES, np.median(f.u_omega, axis=1).tolist()))}
            if f.offsets is not None:
                doc["filter"]["bias_std_m_s2"] = self.bias_std
                doc["filter"]["offsets"] = _offsets(UNKNOWNS[3:], f.offsets, f.u_offsets)
        if self.errors is not None:
            # The headline errors are the converged filter's; the start-up transient is reported beside them.
            doc["errors"] = {m: {ax: s.axis(i) for i, ax in enumerate(_AXES)} for m, s in self.errors.items()}
            doc["errors_from_s"] = self.converged_from_s
            if self.errors_transient is not None:
                doc["errors_transient"] = {
                    "until_s": self.converged_from_s,
                    **{m: {ax: s.axis(i) for i, ax in enumerate(_AXES)} for m, s in self.errors_transient.items()}}
        if self.quaternion is not None:
            doc["attitude"] = {"method": self.attitude_method, "initial_quaternion": list(self.initial_quaternion)}
            ae = self.attitude_error
            if ae is not None:
                doc["attitude"].update(max_error_deg=ae.max_deg, final_error_deg=ae.final_deg,
                                       growth_deg_per_s=ae.growth_deg_per_s, position_drift_m=ae.position_drift_m)
        doc["warnings"] = list(est.warnings)
        return to_jsonable(doc)

    def output_recording(self):
        """What ``--out`` writes: t, w per method (rad/s), alpha (rad/s^2), f (m/s^2) and q.

        One method: columns ``wx, wy, wz``; several: ``<method>_wx`` ...
        """
        from senscal.io import Recording

        est = self.estimate
        chans: dict[str, np.ndarray] = {}
        single = len(est.omega) == 1
        for m, w in est.omega.items():
            for i, ax in enumerate(_AXES):
                chans[ax if single else f"{m}_{ax}"] = w[i]
        kin = est.kinematics
        for i, ax in enumerate("xyz"):
            chans[f"alpha_{ax}"] = kin.angular_acceleration[i]
        for i, ax in enumerate("xyz"):
            chans[f"f_{ax}"] = kin.specific_force[i]
        if self.quaternion is not None:
            chans.update(zip(_QUATERNION, self.quaternion))
        return Recording(channels=chans, t=self.t, allow_nan=True)

    def to_dataframe(self):
        """One row per sample: t (s) and the columns of :meth:`output_recording`."""
        import pandas as pd

        rec = self.output_recording()
        return pd.DataFrame({"t": rec.time, **{k: np.asarray(v) for k, v in rec.channels.items()}})


def _offsets(names, values, us) -> dict[str, dict[str, float]]:
    return {n: {"value": float(v), "u": float(u)} for n, v, u in zip(names, values, us)}


def _check(o: GfimuOptions) -> None:
    """Refuse option combinations the methods cannot honour (one line each, with the fix)."""
    from senscal.gfimu import METHODS, OBSERVATIONS

    if o.lag < 1:
        raise InputError(f"--lag must be at least 1 sample, got {o.lag}")
    # The filter works with variances; beyond 1e100 their products overflow to NaN rates.
    if o.noise_std is not None and not 0 < o.noise_std < 1e100:
        raise InputError(f"--noise-std must be a positive number in m/s^2 (below 1e100), got {o.noise_std:g}")
    if o.bias_std is not None and not 0 < o.bias_std < 1e100:
        raise InputError("--bias-std must be a positive number in m/s^2 (the channels' constant-error uncertainty)")
    if (o.bias_std is not None or o.rest is not None) and o.observation != "quadratic":
        raise InputError("--bias-std and --rest need --observation quadratic (the constant errors are states of that "
                         "filter)")
    if o.bias_std is not None and o.rest is not None:
        raise InputError("--rest measures the constant errors that --bias-std would only bound: give one of them")
    if o.plain and (o.bias_std is not None or o.rest is not None):
        raise InputError("--plain is the filter without constant-error states: drop --bias-std / --rest, or --plain")
    if o.differential_max_u is not None and not 0 < o.differential_max_u < float("inf"):
        raise InputError(f"--differential-max-u must be a positive rate in rad/s, got {o.differential_max_u:g}")
    if o.layout is not None and o.distance is not None:
        raise InputError("give either --layout or --distance, not both")
    if o.method not in METHODS + ("all",):
        raise InputError(f"--method must be one of {', '.join(METHODS)}, all; got {o.method!r}")
    if o.observation not in OBSERVATIONS:
        raise InputError(f"--observation must be one of {', '.join(OBSERVATIONS)}; got {o.observation!r}")
    if len(tuple(o.initial_omega)) != 3:
        raise InputError(f"--initial-omega needs three numbers WX,WY,WZ in rad/s, got {o.initial_omega!r}")
    if o.rest is not None and len(tuple(o.rest)) != 2:
        raise InputError(f"--rest needs START:END in s (e.g. 0:2), got {o.rest!r}")


def _layout_of(o: GfimuOptions) -> tuple[Any, str]:
    from senscal.gfimu import Layout, paper_layout, read_layout

    if o.layout is None:
        d = 0.04 if o.distance is None else o.distance
        return paper_layout(d), f"paper, L = {d} m"
    return given_or_loaded(o.layout, Layout, read_layout, label="<layout>", what="the layout",
                           path="layout CSV path")


def _truth_on(rec_t: np.ndarray, path, need_q: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """Truth ``w`` (3, T) and, if present, ``q`` (4, T) on the recording's time base."""
    tr = read_source(path)
    missing = [c for c in _AXES if c not in tr]
    if missing:
        raise InputError(f"truth file {path} lacks column(s) {', '.join(missing)}; it needs t, wx, wy, wz in rad/s")
    tt = tr.time
    if tt.size == rec_t.size and np.allclose(tt, rec_t, rtol=0, atol=1e-9 * max(1.0, float(np.abs(rec_t).max()))):
        w = tr.data(list(_AXES)) * _si_scales(tr, _AXES, "rad/s", "truth column")[:, None]
        q = tr.data(list(_QUATERNION)) if need_q and all(c in tr for c in _QUATERNION) else None
        return w, q
    if tt[0] > rec_t[0] or tt[-1] < rec_t[-1]:
        raise InputError(f"truth file {path} spans t={tt[0]:g}..{tt[-1]:g} s but the recording "
                         f"{rec_t[0]:g}..{rec_t[-1]:g} s; give a truth that covers the recording")
    w = np.stack([np.interp(rec_t, tt, tr[c]) for c in _AXES]) * _si_scales(tr, _AXES, "rad/s", "truth column")[:, None]
    return w, None


def _si_scales(rec, names, unit: str, what: str) -> np.ndarray:
    """Per channel, the factor into ``unit`` (g -> m/s^2, deg/s -> rad/s); no unit in the file means ``unit``."""
    from senscal.units import factor

    where = rec.source or "the recording"
    return np.array([factor(rec.unit(n) or unit, unit, what=f"{what} '{n}' of {where}",
                            fix=f"give it in {unit} or a unit convertible to it") for n in names])


def _plausibility_warnings(est, rec, y, layout) -> tuple[str, ...]:
    """``time-unit-suspect`` when the time stamps or the rates are physically impossible for the array."""
    from senscal.io.plausibility import TIME_UNIT_WARNING, check_angular_rate

    # The reading layer's time-base warnings (read for "gfimu": its rate limits), then the array's own evidence.
    found = tuple(w for w in rec.warnings if w not in est.warnings)
    if any(w.startswith(TIME_UNIT_WARNING) for w in est.warnings + found):
        return found
    pos = np.asarray(layout.positions, dtype=float)
    radius = float(np.max(np.linalg.norm(pos - pos.mean(axis=0), axis=1))) if pos.size else float("nan")
    # NaN rates (samples a method rejected) are skipped without numpy's all-NaN warnings.  The
    # differential method is left out: its gross errors where the increment is small (1e5 rad/s on an
    # axis that hardly turns) are the method's, not a sign of a wrong time unit.
    norms = [np.linalg.norm(np.asarray(w, dtype=float), axis=0) for m, w in est.omega.items() if m != "differential"]
    rates = [float(n[np.isfinite(n)].max()) for n in norms if np.isfinite(n).any()]
    ay = np.abs(np.asarray(y, dtype=float))
    return found + tuple(check_angular_rate(max(rates, default=float("nan")),
                                            float(ay[np.isfinite(ay)].max()) if np.isfinite(ay).any() else float("nan"),
                                            radius))


def gfimu(source, options: GfimuOptions = GfimuOptions()) -> GfimuResult:
    """Angular velocity of a rigid body from its accelerometer array.

    Parameters
    ----------
    source : str, Path or Recording
        The array's channels (m/s^2), named as in the layout, and time (s).
    options : GfimuOptions

    Returns
    -------
    GfimuResult

    Raises
    ------
    SenscalError
        Contradicting options, unreadable recording or layout, missing
        channel, a truth that does not cover the recording ... (one line,
        with the fix).

    References
    ----------
    The gyro-free IMU Kalman filter of ``../shared/METHODS.md``
    (integration as process, quadratic terms as measurement).
    """
    from senscal.gfimu import DEFAULT_BIAS_STD, METHODS, angular_velocity, attitude_error, convergence_index, \
        error_statistics, integrate_attitude

    o = options
    _check(o)
    layout, layout_source = _layout_of(o)
    methods = METHODS if o.method == "all" else (o.method,)
    w0 = tuple(float(v) for v in o.initial_omega)
    span = None if o.rest is None else tuple(float(v) for v in o.rest)
    rec = o.read(source, job="gfimu")
    y = rec.data(list(layout.names)) * _si_scales(rec, layout.names, "m/s^2", "accelerometer channel")[:, None]
    est = angular_velocity(y, rec.time, layout, methods=methods, observation=o.observation, initial=w0,
                           noise_std=o.noise_std, lag=o.lag, bias_std=o.bias_std, smooth=o.smooth, plain=o.plain,
                           rest=span, differential_max_u=o.differential_max_u)
    extra = _plausibility_warnings(est, rec, y, layout)
    if extra:
        est = replace(est, warnings=tuple(est.warnings) + extra)
    w_true = q_true = errors = transient = None
    k_conv = convergence_index(est.u_omega) if est.u_omega is not None else 0
    if o.truth is not None:
        w_true, q_true = _truth_on(rec.time, o.truth, o.attitude)
        errors = error_statistics(est.omega, w_true, skip=k_conv)
        if k_conv > 0:
            transient = error_statistics({m: w[:, :k_conv] for m, w in est.omega.items()}, w_true[:, :k_conv])
    q = src = q0 = ae = None
    if o.attitude:
        src = "kalman" if "kalman" in est.omega else next(iter(est.omega))
        q0 = tuple(map(float, q_true[:, 0])) if q_true is not None else (1.0, 0.0, 0.0, 0.0)
        q = integrate_attitude(est.omega[src], rec.time, q0)
        if q_true is not None:
            ae = attitude_error(q, q_true, rec.time)
    bias_std = None if o.rest is not None else DEFAULT_BIAS_STD if o.bias_std is None else o.bias_std
    return GfimuResult(estimate=est, source=source_name(source), t=rec.time, sample_rate=rec.sample_rate,
                       layout=layout, layout_source=layout_source, observation=o.observation, initial_omega=w0,
                       bias_std=bias_std, differential_max_u=o.differential_max_u, errors=errors,
                       errors_transient=transient, converged_from_s=float(rec.time[k_conv]), truth_omega=w_true,
                       quaternion=q, attitude_method=src, initial_quaternion=q0, attitude_error=ae,
                       warnings=tuple(est.warnings))
