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
* a drift record spans decades;
* every stamp is a whole number at least 1 apart (1 Hz or slower read as
  seconds): what a clock counting ms or us writes (not for drift, whose
  loggers write whole seconds);
* a header unit (``t [ms]``) that makes the rate higher than the job's
  instruments sample, or higher than recorders that stamp in that unit
  sample (seconds labelled ms: a 1 kHz record becomes 1 MHz);
* a free sine fit whose frequency and sample rate are both far below a
  sine calibration's (ms or us read as seconds, also under ``t [s]``);
* a preamble rate (``Fs,1000``) or ``--fs`` that disagrees with the time
  column: a contradiction, refused (:func:`reconcile_rates`).

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
           "check_span", "check_counter_clock", "check_declared_unit", "reconcile_rates", "MAX_SAMPLE_RATE_HZ",
           "SLOW_LOGGER_JOBS", "RATE_TOLERANCE", "time_base_warnings", "check_time", "with_time_warnings",
           "merge_time_warnings", "MAX_SAMPLE_RATE_IN_UNIT", "SLOW_SINE_HZ", "SLOW_SINE_RATE_HZ",
           "check_fitted_frequency"]

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

#: Highest sample rate a job's instruments plausibly use (Hz): MEMS accelerometers, gyroscopes and
#: magnetometers output at most a few tens of kHz (32 kHz for the fastest); 100 kHz is above all of them.
#: Seconds labelled ms make a 1 kHz recording 1 MHz. Sine fits (oscilloscopes at MS/s to GS/s) and the
#: vibration rigs (checked against their known frequency instead) have no such bound.
MAX_SAMPLE_RATE_HZ = {"gfimu": 1e5, "triaxial": 1e5, "allan": 1e5, "shaft": 1e5, "imu": 1e5}

#: Highest sample rate of a recorder that stamps its time column in this unit (Hz), whatever the job.
#: Stamps in ms at 200 kHz step by 0.005 ms; digitisers that fast (oscilloscopes, fast DAQ) write seconds
#: (often in scientific notation) or us, and a time column in seconds labelled ms turns every DAQ rate from
#: 200 Hz up into 200 kHz and more (1 kHz into 1 MHz). Likewise 200 MHz in us (steps of 5 ns).
MAX_SAMPLE_RATE_IN_UNIT = {"ms": 2e5, "us": 2e8, "\u00b5s": 2e8, "\u03bcs": 2e8}

#: A free sine fit below SLOW_SINE_HZ on samples below SLOW_SINE_RATE_HZ is what a sine calibration in ms
#: (or us) read as seconds gives: 100 Hz on a 10 kHz DAQ becomes 0.1 Hz on 10 Hz. Genuine slow sines
#: (seismometers at 0.01 Hz) are named too; a --freq that the data confirm replaces this check.
SLOW_SINE_HZ = 0.1
SLOW_SINE_RATE_HZ = 10.0

#: Jobs whose records come from slow loggers, where whole-second stamps at 1 Hz or slower are normal.
SLOW_LOGGER_JOBS = frozenset({"drift"})

#: Relative disagreement of two statements of one sample rate (a preamble's Fs, --fs, the time column's
#: mean rate) beyond which they contradict: crystal clocks agree to 1e-4, a host clock's mean rate over a
#: record to a few 1e-3; 1 % is neither, and is far below any unit factor (1000, 60).
RATE_TOLERANCE = 0.01

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
    for unit, factor in UNIT_FACTORS.items():
        if abs(ratio * factor - 1.0) < _RATIO_TOL:
            # The other way round: seconds whose header (or --time-unit) says ms.
            share = {"ms": "1000 times", "us": "1000000 times", "min": "1/60 of"}[unit]
            return (named(TIME_UNIT_WARNING, f"the recording's dominant frequency is {share} {what}, the factor "
                                             f"of time stamps in seconds read as {unit}; fix: give the header as "
                                             "'t [s]' or drop --time-unit"),)
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


def _whole_numbers(t: np.ndarray) -> bool:
    return bool(np.all(np.abs(t - np.round(t)) <= 1e-9 * np.maximum(1.0, np.abs(t))))


def check_counter_clock(t: np.ndarray, job: str | None) -> tuple[str, ...]:
    """Warn when every stamp is a whole number at least 1 apart: a ms or us clock read as seconds.

    A clock counting milliseconds (``millis()``) or microseconds writes whole
    numbers; read as seconds a 1 kHz recording becomes 1 Hz, every frequency
    1000x low. Whole seconds 1 s or more apart are what slow loggers write,
    normal for drift (:data:`SLOW_LOGGER_JOBS`) and suspect elsewhere; a time
    column whose unit is stated (``t [s]``, ``--time-unit s``) is not checked.

    Parameters
    ----------
    t : ndarray
        Time stamps as read (s).
    job : str or None
        The job reading the recording (None: no job-specific check).
    """
    t = np.asarray(t, dtype=float)
    if job is None or job in SLOW_LOGGER_JOBS or t.size < 3:
        return ()
    dt = float(np.median(np.diff(t)))
    if not (math.isfinite(dt) and dt >= 1.0) or not _whole_numbers(t):
        return ()
    return (named(TIME_UNIT_WARNING,
                  f"every time stamp is a whole number, {dt:g} apart ({1.0 / dt:.3g} Hz read as seconds): what a "
                  f"clock counting milliseconds ({1e3 / dt:.3g} Hz) or microseconds ({1e6 / dt:.3g} Hz) writes; "
                  "fix: give the header as 't [ms]' or --time-unit ms (us), or --time-unit s if they are seconds"),)


def check_declared_unit(t: np.ndarray, unit: str, job: str | None) -> tuple[str, ...]:
    """Warn when a stated time unit (``t [ms]``) makes the rate higher than the job's instruments sample.

    Parameters
    ----------
    t : ndarray
        Time stamps converted to seconds with ``unit``.
    unit : str
        The unit the header or ``--time-unit`` gave.
    job : str or None
        Key of :data:`MAX_SAMPLE_RATE_HZ`; other jobs are not checked.
    """
    hi = MAX_SAMPLE_RATE_HZ.get(job or "")
    unit_hi = MAX_SAMPLE_RATE_IN_UNIT.get(unit.strip())
    t = np.asarray(t, dtype=float)
    if (hi is None and unit_hi is None) or t.size < 2:
        return ()
    span = float(t[-1] - t[0])
    if not (math.isfinite(span) and span > 0):
        return ()
    rate = (t.size - 1) / span
    if (hi is None or rate <= hi) and (unit_hi is None or rate <= unit_hi):
        return ()
    if hi is None or rate <= hi:
        u = unit.strip()
        return (named(TIME_UNIT_WARNING,
                      f"the time column is in {u} by its header or --time-unit, which makes the sample rate "
                      f"{rate:.4g} Hz; recorders faster than {unit_hi:.3g} Hz stamp in s (or a finer unit), not {u}, "
                      f"and seconds labelled {u} look like this ({rate * _IN_SECONDS[u]:.4g} Hz in seconds); fix: "
                      "give the header as 't [s]' if the values are seconds"),)
    return (named(TIME_UNIT_WARNING,
                  f"the time column is in {unit.strip()} by its header or --time-unit, which makes the sample rate "
                  f"{rate:.4g} Hz, above any {job} instrument (<= {hi:g} Hz); seconds labelled {unit.strip()} "
                  f"look like this; fix: give the header as 't [s]' if the values are seconds"),)


_IN_SECONDS = {"ms": 1e-3, "us": 1e-6, "\u00b5s": 1e-6, "\u03bcs": 1e-6}


def check_fitted_frequency(t: np.ndarray, frequency_hz: float) -> tuple[str, ...]:
    """Warn when a free sine fit's frequency and the sample rate are both far below a sine calibration's.

    Both scale with the time unit, so their ratio says nothing; their size
    does: below :data:`SLOW_SINE_HZ` on samples slower than
    :data:`SLOW_SINE_RATE_HZ` is what a record stamped in ms (or us) read as
    seconds shows. Not for a fit at a known frequency (``--freq``), which
    :func:`check_known_frequency` compares with the data instead.

    Parameters
    ----------
    t : ndarray
        Time stamps as read (s).
    frequency_hz : float
        The fitted frequency (Hz).
    """
    t = np.asarray(t, dtype=float)
    if t.size < 2 or not (math.isfinite(frequency_hz) and frequency_hz > 0):
        return ()
    span = float(t[-1] - t[0])
    if not (math.isfinite(span) and span > 0):
        return ()
    rate = (t.size - 1) / span
    if frequency_hz >= SLOW_SINE_HZ or rate >= SLOW_SINE_RATE_HZ:
        return ()
    return (named(TIME_UNIT_WARNING,
                  f"the fitted frequency {frequency_hz:.4g} Hz on samples at {rate:.4g} Hz is what a time column in "
                  f"ms read as seconds gives (in ms: {1e3 * frequency_hz:.4g} Hz at {1e3 * rate:.4g} Hz; in us: "
                  f"{1e6 * frequency_hz:.4g} Hz); fix: give the header as 't [ms]' or --time-unit ms (us), or "
                  "--time-unit s (or --freq) if the values are seconds and the frequency is this low"),)


def _factor_name(ratio: float) -> str | None:
    """The unit mix-up a rate ratio (time column / stated) is, if it is one: 'ms', 'us', 'min', 's-as-ms' ..."""
    for unit, factor in UNIT_FACTORS.items():
        if abs(ratio / factor - 1.0) < _RATIO_TOL:
            return unit
    for unit, factor in UNIT_FACTORS.items():
        if abs(ratio * factor - 1.0) < _RATIO_TOL:
            return "s-as-" + unit
    return None


def reconcile_rates(t: np.ndarray | None, *, file_fs: float | None, user_fs: float | None, source: str,
                    time_name: str = "t", file_fs_text: str = "Fs") -> None:
    """Refuse a sample rate stated twice (preamble ``Fs``, ``--fs``, the time column) with two values.

    Agreement is within :data:`RATE_TOLERANCE`; the time column's rate is its
    mean rate ``(n - 1) / span``. A disagreement by a unit factor (1000, 1e6,
    60) says so and names the fix.

    Parameters
    ----------
    t : ndarray or None
        Time column in seconds (None: the file has none).
    file_fs : float or None
        Sample rate the file states about itself (CSV preamble, TDMS increment, HDF5 attribute), Hz.
    user_fs : float or None
        ``--fs`` (Hz).
    source : str
        File name for the message.
    time_name : str
        Name of the time column for the message.
    file_fs_text : str
        How the file states its rate, for the message (``'Fs,1000'``).

    Raises
    ------
    InputError
        Two of the statements disagree (one line naming both and the fix).
    """
    from senscal.errors import InputError

    col = None
    if t is not None and np.asarray(t).size > 1:
        t = np.asarray(t, dtype=float)
        span = float(t[-1] - t[0])
        col = (t.size - 1) / span if span > 0 and math.isfinite(span) else math.nan

    def agree(a: float, b: float) -> bool:
        return math.isfinite(a) and math.isfinite(b) and abs(a / b - 1.0) <= RATE_TOLERANCE

    if user_fs is not None and file_fs is not None and not agree(user_fs, file_fs):
        raise InputError(f"--fs {user_fs:g} Hz contradicts {source}, which states its sample rate as "
                         f"{file_fs:g} Hz ({file_fs_text}); drop --fs, or skip the file's preamble with --skip-rows "
                         "if its rate is wrong")
    if col is not None and file_fs is not None and not agree(col, file_fs):
        mix = _factor_name(col / file_fs) if math.isfinite(col) else None
        if mix is not None and not mix.startswith("s-as-"):
            fix = f"the time column looks like {mix} read as seconds: give the header as '{time_name} [{mix}]' or --time-unit {mix}"
        elif mix is not None:
            fix = (f"the time column looks like seconds labelled {mix[5:]}: give the header as '{time_name} [s]' "
                   "or drop --time-unit")
        else:
            fix = ("fix the file, or read it without the preamble (--skip-rows) or without the time column "
                   "(--time-column none --fs HZ)")
        raise InputError(f"the time column '{time_name}' of {source} gives {col:.6g} samples/s but the file states "
                         f"{file_fs:g} Hz ({file_fs_text}); {fix}")
    if col is not None and user_fs is not None and not agree(col, user_fs):
        mix = _factor_name(col / user_fs) if math.isfinite(col) else None
        hint = f" (a factor of a time column in {mix} read as seconds)" if mix and not mix.startswith("s-as-") else ""
        raise InputError(f"--fs {user_fs:g} Hz contradicts the time column '{time_name}' of {source} "
                         f"(about {col:.6g} samples/s{hint}); --fs is for files without a time column")


def time_base_warnings(t: np.ndarray, job: str | None, *, unit: str | None = None,
                       declared: bool = False) -> tuple[str, ...]:
    """The suspicions about a time column that reading can name, for the job the recording is read for.

    Parameters
    ----------
    t : ndarray
        Time stamps in seconds (converted with ``unit`` when one was stated).
    job : str or None
        The job (limits of :data:`MIN_SAMPLE_RATE_HZ`, :data:`MAX_SAMPLE_RATE_HZ`, :data:`MAX_SPAN_S`).
    unit : str, optional
        A unit other than seconds that the header or ``--time-unit`` stated (``ms``).
    declared : bool
        A unit was stated (``t [s]``, ``--time-unit s``): the checks of what
        clocks write (whole numbers, logger intervals) are skipped.

    Returns
    -------
    tuple of str
        At most one ``time-unit-suspect`` warning.
    """
    # The most specific message first: all say "the time is not in the unit it is read in".
    found = check_epoch_ms(t)
    if not declared:
        # What clocks write (whole numbers, logger intervals) is only a suspicion where no unit was stated.
        found += check_counter_clock(t, job) + check_logger_interval(t)
    if job is not None:
        found += check_sample_rate(t, job) + check_span(t, job)
    if unit is not None:
        found += check_declared_unit(t, unit, job)
    return found[:1]


def merge_time_warnings(warnings, read: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """``warnings`` plus the reading layer's time-base warnings ``read``: no repeat, one ``time-unit-suspect``.

    A job may find its own evidence of a wrong time unit (a known frequency,
    an impossible angular rate); the reading layer's is added only when the
    job named none, since both say the same thing.
    """
    out = list(warnings)
    have = {w.split(":", 1)[0] for w in out}
    for w in read:
        name = w.split(":", 1)[0]
        if w in out or (name == TIME_UNIT_WARNING and name in have):
            continue
        out.append(w)
        have.add(name)
    return tuple(out)


def check_time(t: np.ndarray, job: str, *, y: np.ndarray | None = None, known_hz: float | None = None,
               what: str = "--freq") -> tuple[str, ...]:
    """Every check that applies: :func:`time_base_warnings` and, with ``y`` and ``known_hz``, the frequency.

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
    # The reading layer's rule for a time column of no stated unit (time_base_warnings), plus the frequency.
    found = time_base_warnings(t, job)
    if y is not None and known_hz is not None:
        found = check_known_frequency(dominant_frequency(y, t), known_hz, what=what) + found
    return found[:1]


def with_time_warnings(result, t: np.ndarray, job: str, *, y: np.ndarray | None = None,
                       known_hz: float | None = None):
    """``result`` (a frozen dataclass with ``warnings``) plus the :func:`check_time` warning, if one fires and is new."""
    from dataclasses import replace

    new = tuple(w for w in check_time(t, job, y=y, known_hz=known_hz) if w not in result.warnings)
    return replace(result, warnings=tuple(result.warnings) + new) if new else result
