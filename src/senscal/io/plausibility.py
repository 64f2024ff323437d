"""Cheap checks that a recording's time column really is in seconds.

A time column in milliseconds under a bare ``t`` header is read as seconds:
every frequency comes out 1000x low, every rate 1000x high, and nothing
fails. Where something is known about the job, the wrong unit shows:

* a frequency the user gave (``--freq``) is 1000x (or 10^6x, or 1/60) the
  dominant frequency of the recording, exactly the factor between seconds
  and ms, us or min;
* the sample rate is far below anything the job's instruments use (a
  vibration calibration sampled at 1 Hz is a 1 kHz recording in ms);
* the first time stamp is a Unix time in milliseconds (1e11..1e14 "s" is
  the years 5000 to 3 million);
* a sample interval that is a whole-second logger interval in ms (300000);
* an angular rate whose centripetal load is far beyond what an accelerometer
  array reads;
* a drift record spans decades.

Each check returns a tuple of named warnings (empty when plausible); the
caller adds them to its result so ``--strict`` exits 3. Pure functions of
arrays and numbers.
"""

from __future__ import annotations

import math

import numpy as np

from senscal.diagnostics import named

__all__ = ["TIME_UNIT_WARNING", "UNIT_FACTORS", "MIN_SAMPLE_RATE_HZ", "MAX_SPAN_S", "dominant_frequency",
           "check_known_frequency", "check_sample_rate", "check_angular_rate", "check_epoch_ms", "check_logger_interval",
           "check_span",
           "check_time", "with_time_warnings"]

TIME_UNIT_WARNING = "time-unit-suspect"

#: Factor (estimated / true frequency) when the time column is in this unit but read as seconds.
UNIT_FACTORS = {"ms": 1e-3, "us": 1e-6, "min": 60.0}

#: Lowest sample rate a job's instruments plausibly use (Hz), and why.
MIN_SAMPLE_RATE_HZ = {
    # Vibration calibrations sample the excitation (>= 0.1 Hz on a hydraulic rig, kHz on a shaker)
    # with many samples per period; 5 Hz is below any DAQ used for them.
    "velocity": 5.0,
    "response": 5.0,
    # Accelerometer arrays track body motion of a few Hz and faster; an IMU below 10 Hz cannot.
    "gfimu": 10.0,
}

#: Longest record a job plausibly holds (s): a drift record over decades outlives the sensor.
MAX_SPAN_S = {"drift": 20 * 365.25 * 86400.0}

# Relative tolerance of a frequency ratio to match a unit factor: a dominant frequency from a
# periodogram of >= a few periods is good to a few per cent; a true unit error matches to ~1e-3.
_RATIO_TOL = 0.05

_FIX = "fix: give the header as 't [{u}]' or --time-unit {u}"


def _suspect(text: str, unit: str = "ms") -> str:
    return named(TIME_UNIT_WARNING, f"{text}; {_FIX.format(u=unit)}")


def dominant_frequency(y: np.ndarray, t: np.ndarray) -> float:
    """Frequency of the largest periodogram peak of ``y`` (cycles per unit of ``t``).

    Parameters
    ----------
    y : ndarray, shape (n,)
        Samples (offset removed here).
    t : ndarray, shape (n,)
        Time stamps, uniformly spaced (the median step is used).

    Returns
    -------
    float
        Peak frequency refined by parabolic interpolation of the log
        spectrum (NaN for fewer than 8 samples or a flat signal).
    """
    y = np.asarray(y, dtype=float)
    t = np.asarray(t, dtype=float)
    ok = np.isfinite(y)
    if ok.sum() < 8 or t.size < 8:
        return math.nan
    dt = float(np.median(np.diff(t)))
    if not (dt > 0 and math.isfinite(dt)):
        return math.nan
    yc = np.where(ok, y - np.mean(y[ok]), 0.0)
    n = yc.size
    spec = np.abs(np.fft.rfft(yc * np.hanning(n))) ** 2
    spec[0] = 0.0
    k = int(np.argmax(spec))
    if spec[k] <= 0:
        return math.nan
    shift = 0.0
    if 0 < k < spec.size - 1:
        a, b, c = np.log(spec[k - 1:k + 2] + 1e-300)
        den = a - 2 * b + c
        shift = 0.5 * (a - c) / den if den < 0 else 0.0
    return (k + shift) / (n * dt)


def check_known_frequency(estimated_hz: float, known_hz: float, *, what: str = "--freq") -> tuple[str, ...]:
    """Warn when a known frequency is a time-unit factor away from the recording's.

    Parameters
    ----------
    estimated_hz : float
        Frequency found in the recording with its time read as seconds.
    known_hz : float
        Frequency the user or the rig states (Hz).
    what : str
        Name of the known value in the message.
    """
    if not (math.isfinite(estimated_hz) and math.isfinite(known_hz) and estimated_hz > 0 and known_hz > 0):
        return ()
    ratio = estimated_hz / known_hz
    for unit, factor in UNIT_FACTORS.items():
        if abs(ratio / factor - 1.0) < _RATIO_TOL:
            # No per-file numbers: the same suspicion over many files is one warning.
            share = {"ms": "1/1000 of", "us": "1/1000000 of", "min": "60 times"}[unit]
            return (_suspect(f"the recording's dominant frequency is {share} {what}, the factor of a time "
                             f"column in {unit} read as seconds", unit),)
    return ()


def check_sample_rate(t: np.ndarray, job: str) -> tuple[str, ...]:
    """Warn when the sample rate is below anything the job's instruments use.

    Parameters
    ----------
    t : ndarray
        Time stamps as read (s).
    job : str
        Key of :data:`MIN_SAMPLE_RATE_HZ`; other jobs are not checked.
    """
    lo = MIN_SAMPLE_RATE_HZ.get(job)
    t = np.asarray(t, dtype=float)
    if lo is None or t.size < 2:
        return ()
    dt = float(np.median(np.diff(t)))
    if not (dt > 0 and math.isfinite(dt)) or 1.0 / dt >= lo:
        return ()
    whole = bool(np.all(np.abs(t - np.round(t)) <= 1e-9 * np.maximum(1.0, np.abs(t))))
    look = ", and whole-number time stamps are what a clock in milliseconds writes" if whole else ""
    return (_suspect(f"a sample interval of {dt:g} s ({1.0 / dt:.3g} Hz) is implausible for {job} (instruments "
                     f"sample at >= {lo:g} Hz){look}; in ms every frequency is 1000x low and every rate 1000x high"),)


def check_angular_rate(omega_max: float, accel_max: float, radius: float, *,
                       factor: float = 100.0) -> tuple[str, ...]:
    """Warn when an angular rate would push an accelerometer array far beyond what it reads.

    A rigid body turning at ``omega`` loads sensors ``radius`` apart from
    their centre with centripetal accelerations of order ``omega^2 radius``;
    the readings differ by that much at least on some channel of an
    observable layout. A rate with ``omega^2 radius`` more than ``factor``
    times the largest reading plus g cannot be the body's; integrated over
    time stamps 1000x too long (ms read as s), rates come out 1000x high.

    Parameters
    ----------
    omega_max : float
        Largest estimated rate magnitude, rad/s.
    accel_max : float
        Largest absolute reading of any channel, m/s^2.
    radius : float
        Largest distance of a sensor from the sensors' centroid, m.
    factor : float
        Margin (projections onto sensing directions, gravity, noise).
    """
    if not all(math.isfinite(v) for v in (omega_max, accel_max, radius)) or radius <= 0:
        return ()
    centripetal = omega_max ** 2 * radius
    if centripetal <= factor * (abs(accel_max) + 9.81):
        return ()
    return (_suspect(f"an angular rate of {omega_max:.4g} rad/s would load sensors {radius:.3g} m from the array's "
                     f"centre with {centripetal:.3g} m/s^2, but no channel reads more than {accel_max:.3g} m/s^2; "
                     "rates integrated over time stamps in ms read as s come out 1000x high"),)


def check_epoch_ms(t: np.ndarray) -> tuple[str, ...]:
    """Warn when the first time stamp looks like a Unix time in milliseconds.

    1e11 to 1e14 read as seconds is the years 5138 to 3 million; as
    milliseconds it is 1973 to 5138.
    """
    t = np.asarray(t, dtype=float)
    if t.size == 0 or not math.isfinite(float(t[0])) or not (1e11 <= float(t[0]) < 1e14):
        return ()
    return (_suspect(f"the first time stamp {float(t[0]):.6g} s lies in the year {1970 + float(t[0]) / 3.15576e7:.0f}; "
                     "it looks like a Unix time in milliseconds"),)


def check_logger_interval(t: np.ndarray) -> tuple[str, ...]:
    """Warn when the sample interval is a logger's whole-second interval written in milliseconds.

    A logger in seconds writes intervals that divide a day (1, 10, 60, 300,
    3600 s ...) or are whole days; ``300000`` is neither, but is 300 s in ms.
    Fires when every step is the same whole multiple of 1000, that multiple
    divides a day, and the step itself neither divides a day nor is whole days.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        return ()
    steps = np.diff(t)
    dt = float(np.median(steps))
    if not (math.isfinite(dt) and dt >= 1000.0 and dt == round(dt) and np.all(steps == dt)):
        return ()
    day = 86400
    ms, whole = int(dt), int(dt)
    if ms % 1000 or day % (ms // 1000) or day % whole == 0 or whole % day == 0:
        return ()
    return (_suspect(f"every sample interval is {dt:g} s, not a logger interval in seconds, but {ms // 1000} s "
                     "written in milliseconds"),)


def check_span(t: np.ndarray, job: str) -> tuple[str, ...]:
    """Warn when a record is longer than the job plausibly records (:data:`MAX_SPAN_S`)."""
    hi = MAX_SPAN_S.get(job)
    t = np.asarray(t, dtype=float)
    if hi is None or t.size < 2:
        return ()
    span = float(t[-1] - t[0])
    if not (math.isfinite(span) and span > hi):
        return ()
    return (_suspect(f"the record spans {span / 3.15576e7:.3g} years, longer than a {job} record plausibly "
                     f"runs (limit {hi / 3.15576e7:.0f} years); in ms it would be {span / 3.15576e10:.3g} years"),)


def check_time(t: np.ndarray, job: str, *, y: np.ndarray | None = None, known_hz: float | None = None,
               what: str = "--freq") -> tuple[str, ...]:
    """Every check that applies: epoch ms, sample rate, span and, with ``y`` and ``known_hz``, the frequency.

    Parameters
    ----------
    t : ndarray
        Time stamps as read (s).
    job : str
        velocity, response, gfimu, drift, ... (selects the limits).
    y : ndarray, optional
        An excited channel, whose dominant frequency is compared with ``known_hz``.
    known_hz : float, optional
        A frequency known independently of the time column (Hz).

    Returns
    -------
    tuple of str
        Named ``time-unit-suspect`` warnings; at most one (the first that fires),
        since they all say the same thing.
    """
    found = check_epoch_ms(t) + check_sample_rate(t, job) + check_logger_interval(t) + check_span(t, job)
    if y is not None and known_hz is not None:
        found = check_known_frequency(dominant_frequency(y, t), known_hz, what=what) + found
    return found[:1]


def with_time_warnings(result, t: np.ndarray, job: str, *, y: np.ndarray | None = None,
                       known_hz: float | None = None):
    """``result`` (a frozen dataclass with ``warnings``) plus the :func:`check_time` warning, if one fires and is new."""
    from dataclasses import replace

    new = tuple(w for w in check_time(t, job, y=y, known_hz=known_hz) if w not in result.warnings)
    return replace(result, warnings=tuple(result.warnings) + new) if new else result
