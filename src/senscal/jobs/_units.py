"""Units of the channels a job reads, as quantities: one unit per channel across files, triads checked.

The jobs ``imu``, ``primary`` and ``shock`` take the units written in a file's
header (``ax [g]``, ``gx [deg/s]``, ``out [mV]``, ``temp [degF]``) and
convert where the physics allows it, refusing with one line where it does not
(:mod:`senscal.units`).  A number whose unit is only a label (a sensitivity of
one file in V per m/s^2 beside another's in mV per m/s^2, both called
"output per m/s^2") is what this module prevents.
"""

from __future__ import annotations

from senscal.errors import InputError

__all__ = ["CommonUnit", "rate_factor", "check_triad_unit", "temperature_in", "celsius_if_other_degree",
           "check_session_time", "LONGEST_SESSION_S", "check_magnitude", "check_time_magnitude", "MAX_ABS",
           "one_side_unit"]


class CommonUnit:
    """The unit of one channel across several recordings: later files are converted to the first file's unit.

    Parameters
    ----------
    channel : str
        The channel's name (for messages).
    option : str
        The option that names it (``--output``), for messages.

    Attributes
    ----------
    unit : str or None
        The first file's unit ('' when its header gives none; None before any file).
    """

    def __init__(self, channel: str, option: str):
        self.channel, self.option = channel, option
        self.unit: str | None = None
        self._first = ""

    def factor(self, unit: str, source: str) -> float:
        """The number this file's channel (in ``unit``) is multiplied by to be in the first file's unit.

        Raises
        ------
        InputError
            One file states a unit and another none, or the units are of different dimensions.
        """
        from senscal.units import factor, same_unit

        u = (unit or "").strip()
        if self.unit is None:
            self.unit, self._first = u, source
            return 1.0
        if bool(u) != bool(self.unit):
            said, silent = (source, self._first) if u else (self._first, source)
            shown = u or self.unit
            raise InputError(f"{self.option} {self.channel}: {said} gives its unit ({shown}) and {silent} none, so "
                             f"their results cannot be put on one scale; write the unit in every file's header "
                             f"('{self.channel} [{shown}]') or in none")
        if same_unit(u, self.unit):
            return 1.0
        return factor(u, self.unit, what=f"channel '{self.channel}' of {source}",
                      fix=f"every file's {self.option} channel must measure the same quantity "
                          f"({self.unit} in {self._first})")


def _dimension_ok(unit: str, want: str) -> bool:
    """Whether a triad channel's ``unit`` fits: the physical quantity ``want``, a raw reading, or unknown text."""
    from senscal.units import compatible, is_unit, is_voltage

    if not unit or not is_unit(unit):
        return True  # no unit, or a label senscal cannot parse ('raw', 'adc'): a reading of unknown scale
    return compatible(unit, want) or compatible(unit, "1") or is_voltage(unit)


def check_triad_unit(unit: str, *, accel: bool, channels, source: str) -> None:
    """Refuse an accelerometer triad in a unit of another dimension (or a gyro's), naming the likely swap.

    A triad may be in its physical unit (m/s^2, g; rad/s, deg/s, deg/h), in counts or volts (raw
    readings), or unlabelled.

    Raises
    ------
    InputError
        ``--accel-channels`` in rad/s, ``--gyro-channels`` in m/s^2, either in m, T, degC ...
    """
    from senscal.units import dimension_of

    want, opt, other = ("m/s^2", "--accel-channels", "--gyro-channels") if accel else \
        ("rad/s", "--gyro-channels", "--accel-channels")
    if _dimension_ok(unit, want):
        return
    dim = dimension_of(unit)
    hint = (f"swapped {opt} and {other}?" if dim == ("an angular velocity" if accel else "an acceleration") else
            f"name the {'accelerometer' if accel else 'gyroscope'}'s channels")
    raise InputError(f"{opt} {','.join(channels)} of {source} are in {unit} ({dim}), not {dimension_of(want)}, "
                     f"counts or volts: {hint}")


def one_side_unit(channels, units, calibration_unit: str) -> str | None:
    """What a saved calibration's ``apply`` assumes when a unit is stated on one side only, None when it assumes nothing.

    Data without a unit are read as in the calibration's unit, and data with a unit against a calibration
    without one are read as in its unknown unit: right only when the two happen to agree (uT data read as nT
    is a factor of 1000).  The caller names the returned text in its ``<job>-units-assumed`` warning.

    Parameters
    ----------
    channels : sequence of str
        The channels applied to.
    units : mapping
        Channel -> the data's unit ('' or missing when the header gives none).
    calibration_unit : str
        The unit the calibration was made in ('' when unknown).

    Returns
    -------
    str or None
        ``"x,y,z in uT read as the calibration's unknown unit"`` or ``"x,y,z without a unit read as the
        calibration's nT"``.
    """
    cu = (calibration_unit or "").strip()
    odd = [c for c in channels if bool((units.get(c) or "").strip()) != bool(cu)]
    if not odd:
        return None
    du = (units.get(odd[0]) or "").strip()
    return (f"{','.join(odd)} in {du} read as the calibration's unknown unit" if du else
            f"{','.join(odd)} without a unit read as the calibration's {cu}")


def rate_factor(unit: str) -> float | None:
    """The factor from a gyro's ``unit`` to rad/s (``deg/s``, ``deg/h``, ``mrad/s``, ``rpm``), None when not a rate."""
    from senscal.units import compatible, factor, is_unit

    if not unit or not is_unit(unit) or not compatible(unit, "rad/s"):
        return None
    return factor(unit, "rad/s")


def celsius_if_other_degree(values, unit: str):
    """Temperatures whose degree differs from the kelvin's (degF, mK) in degC; others as they are.

    The temperature terms count their swing and coefficients per unit of the channel: a degF or a mK is
    not the kelvin the swing check (``senscal.imu.calibrate.MIN_SWING_K``) and the reader expect.

    Returns
    -------
    values : ndarray
    unit : str
    """
    import numpy as np

    from senscal.units import compatible, convert, is_unit

    if not unit or not is_unit(unit) or not compatible(unit, "K"):
        return values, unit
    step = np.diff(convert(np.array([0.0, 1.0]), unit, "K"))[0]
    if abs(step - 1.0) <= 1e-12:
        return values, unit  # K, degC
    return convert(values, unit, "degC", what="the temperature channel"), "degC"


def temperature_in(values, have: str, want: str, *, channel: str, source: str):
    """A temperature channel in the calibration's unit (offsets included: degF, K into degC).

    Either unit unknown: the values as they are (the caller names the assumption).

    Raises
    ------
    InputError
        A unit of another dimension (a temperature channel in V against degC).
    """
    from senscal.units import convert, is_unit

    if not have or not want or not is_unit(have) or not is_unit(want):
        return values
    return convert(values, have, want, what=f"temperature channel '{channel}' of {source}",
                   fix="give the IMU's temperature channel, or convert it")


#: No IMU, interferometer or shock session lasts longer (about four months); a longer time column is not in seconds.
LONGEST_SESSION_S = 1e7


def check_session_time(rec, source: str, job: str) -> None:
    """Refuse a time column that cannot be seconds: spanning beyond :data:`LONGEST_SESSION_S`, or not finite.

    The fits of these jobs put the time (and its square, in drift terms) into their design matrices: a
    column in ns read as s, or scaled by 1e300, overflows them; the message names the unit instead.

    Raises
    ------
    InputError
    """
    import math

    span = rec.duration
    if not math.isfinite(span) or span > LONGEST_SESSION_S:
        raise InputError(f"{source}: the time column spans {span:.3g} s, longer than any {job} session: it is not "
                         "in seconds; write its unit in the header ('t [ms]', 't [us]') or give --time-unit, or "
                         "--fs when the file has no time column")


#: Largest magnitude a channel may reach: the fits square the readings, and beyond ~1e154 squares overflow float64
#: (the rule of senscal.sinefit, senscal.triaxial and senscal.shaft).
MAX_ABS = 1e150


def check_magnitude(rec, channels, source: str) -> None:
    """Refuse a channel whose readings reach beyond :data:`MAX_ABS` (the fits' squares would overflow).

    Raises
    ------
    InputError
    """
    import numpy as np

    for c in channels:
        v = np.asarray(rec.channels[c], float)
        peak = float(np.nanmax(np.abs(v))) if v.size and not np.all(np.isnan(v)) else 0.0
        if peak > MAX_ABS:
            raise InputError(f"{source}: channel '{c}' reaches {peak:.3g}, beyond the 1e150 the fits can square in "
                             "float64; check the channel and its unit, or rescale it")


def check_time_magnitude(rec, source: str) -> None:
    """Refuse a time column reaching beyond :data:`MAX_ABS` seconds (the fits square the time, as the readings).

    For jobs without a longest session (a sine fit of any record): a column scaled by 1e300 made the sine fit's
    solver fail inside (an internal error) instead of naming the column.

    Raises
    ------
    InputError
    """
    import numpy as np

    t = np.asarray(rec.time, float)
    peak = float(np.max(np.abs(t))) if t.size else 0.0
    if not np.isfinite(peak) or peak > MAX_ABS:
        how = ("the time column" if getattr(rec, "t", None) is not None else
               f"the time of --fs {rec.fs:g} Hz")
        fix = ("write its unit in the header ('t [ms]', 't [us]') or give --time-unit, or rescale it"
               if getattr(rec, "t", None) is not None else "give the sample rate in Hz")
        raise InputError(f"{source}: {how} reaches {peak:.3g} s, beyond the 1e150 the fits can square in float64: "
                         f"it is not in seconds; {fix}")
