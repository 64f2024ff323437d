"""The one in-memory type for a recording: named channels on a time base."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from senscal.errors import DataError, InputError, TooFewSamplesError, UnknownChannelError

__all__ = ["Recording", "check_finite", "check_time", "sample_rate_of", "is_regular"]


def _first_bad(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def check_finite(name: str, values: np.ndarray, *, source: str | None = None, allow_nan: bool = False) -> None:
    """Raise :class:`DataError` naming the channel and first bad row.

    Rows are counted from 1, as a user counts the data rows of a file below its header.

    Parameters
    ----------
    name : str
        Channel name used in the message.
    values : ndarray
        1-D samples.
    source : str, optional
        File name used in the message.
    allow_nan : bool
        When true, NaN is accepted as "missing" but +/-inf still is not.
    """
    bad = np.isinf(values) if allow_nan else ~np.isfinite(values)
    if bad.any():
        row = _first_bad(bad)
        where = f" in {source}" if source else ""
        kind = "NaN" if np.isnan(values[row]) else "inf"
        raise DataError(
            f"channel '{name}'{where} has {kind} in data row {row + 1} (and {int(bad.sum()) - 1} more); "
            "remove or interpolate the bad samples before calibrating"
        )


def check_time(t: np.ndarray, *, source: str | None = None, name: str = "t") -> None:
    """Raise :class:`DataError` unless ``t`` is finite and strictly increasing."""
    where = f" in {source}" if source else ""
    if not np.all(np.isfinite(t)):
        row = _first_bad(~np.isfinite(t))
        raise DataError(f"time column '{name}'{where} is not finite in data row {row + 1}; fix the time stamps")
    if t.size > 1:
        d = np.diff(t)
        if np.any(d <= 0):
            row = _first_bad(d <= 0) + 1
            what = "duplicate" if d[row - 1] == 0 else "non-monotonic (goes backwards)"
            raise DataError(
                f"time column '{name}'{where} is {what} in data row {row + 1} "
                f"(t={float(t[row - 1])!r} then {float(t[row])!r}); time stamps must strictly increase"
            )


def is_regular(t: np.ndarray) -> bool:
    """True when time stamps ``t`` (s) are equally spaced within rounding (1e-6 of the spacing).

    Stamps far from zero carry rounding jitter of ~1e-16 * |t|, which is allowed for.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        return True
    d = np.diff(t)
    tol = 1e-6 * float(np.mean(d)) + 4e-16 * float(np.max(np.abs(t)))
    return bool(np.ptp(d) <= tol)


def sample_rate_of(t: np.ndarray) -> float:
    """The sample rate (Hz) of time stamps ``t`` (s): the one rule every job uses.

    The mean rate over the record, ``(n - 1) / (t[-1] - t[0])``: for equally
    spaced stamps it is 1 / their spacing (and more exact than any single
    interval: stamps near 1.7e9 s carry 2e-7 s of rounding each), for
    irregular ones (a host clock stamping bursts of buffered samples, jitter)
    it counts every sample once over the time they took. The median interval
    of bursty host stamps is the spacing inside a burst (2 ms for a 100 Hz
    MPU6050 read in bursts: 5x the rate).

    Raises
    ------
    TooFewSamplesError
        Fewer than two stamps.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        raise TooFewSamplesError("a single sample has no sample rate")
    return float((t.size - 1) / (t[-1] - t[0]))


@dataclass(frozen=True)
class Recording:
    """Named channels sampled on one time base.

    Parameters
    ----------
    channels : mapping of str to array_like
        Channel name -> 1-D samples (converted to float64), all the same length.
    t : array_like, optional
        Time stamps in seconds, strictly increasing.  Give ``t`` or ``fs``.
    fs : float, optional
        Sample rate in Hz of a uniform record that starts at ``t0``.
    t0 : float
        Start time in seconds when ``fs`` is given (default 0).
    units : mapping of str to str, optional
        Unit of each channel (e.g. ``"m/s^2"``, ``"V"``).
    metadata : mapping, optional
        Free-form information (sensor, operator, file properties).
    source : str, optional
        Where the recording came from (file path), used in messages.
    allow_nan : bool
        Accept NaN as missing samples (inf is always refused).
    warnings : tuple of str
        Named warnings about the time base found while reading the file
        (``time-unit-suspect: ...``); every job adds them to its result.

    Notes
    -----
    Time is never re-zeroed: ``time`` is exactly what the file said.
    """

    channels: Mapping[str, np.ndarray]
    t: np.ndarray | None = None
    fs: float | None = None
    t0: float = 0.0
    units: Mapping[str, str] = field(default_factory=dict)
    metadata: Mapping[str, Any] = field(default_factory=dict)
    source: str | None = None
    allow_nan: bool = False
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        chans: dict[str, np.ndarray] = {}
        n = None
        for name, values in dict(self.channels).items():
            try:
                arr = np.array(values, dtype=np.float64, copy=True)
            except (TypeError, ValueError) as exc:
                raise DataError(f"channel '{name}' holds non-numeric values; keep only numbers in data columns") from exc
            if arr.ndim != 1:
                raise InputError(f"channel '{name}' must be 1-D, got shape {arr.shape}")
            if n is None:
                n = arr.size
            elif arr.size != n:
                raise InputError(f"channel '{name}' has {arr.size} samples but others have {n}; channels must share one time base")
            check_finite(name, arr, source=self.source, allow_nan=self.allow_nan)
            arr.setflags(write=False)
            chans[str(name)] = arr
        if not chans:
            raise InputError(f"recording{' ' + self.source if self.source else ''} has no data channels")
        object.__setattr__(self, "channels", MappingProxyType(chans))
        if (self.t is None) == (self.fs is None):
            raise InputError("give exactly one of t (time stamps) or fs (sample rate)")
        if self.t is not None:
            t = np.array(self.t, dtype=np.float64, copy=True)
            if t.ndim != 1 or t.size != n:
                raise InputError(f"time vector has {t.size} samples but channels have {n}")
            check_time(t, source=self.source)
            t.setflags(write=False)
            object.__setattr__(self, "t", t)
        else:
            fs = float(self.fs)  # type: ignore[arg-type]
            if not np.isfinite(fs) or fs <= 0:
                raise InputError(f"sample rate must be a positive number of Hz, got {self.fs!r}")
            object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "units", MappingProxyType(dict(self.units)))
        object.__setattr__(self, "metadata", MappingProxyType(dict(self.metadata)))
        object.__setattr__(self, "warnings", tuple(str(w) for w in self.warnings))

    # -- basic facts ---------------------------------------------------------
    @property
    def names(self) -> list[str]:
        """Channel names in file order."""
        return list(self.channels)

    @property
    def n_samples(self) -> int:
        """Number of samples per channel."""
        return next(iter(self.channels.values())).size

    @property
    def time(self) -> np.ndarray:
        """Time stamps in seconds (built from ``fs`` and ``t0`` if needed)."""
        if self.t is not None:
            return self.t
        return self.t0 + np.arange(self.n_samples) / self.fs

    @property
    def is_uniform(self) -> bool:
        """True when samples are equally spaced (within 1e-6 of the spacing)."""
        if self.fs is not None or self.n_samples < 3:
            return True
        return is_regular(self.t)

    @property
    def sample_rate(self) -> float:
        """Sample rate in Hz: ``fs``, or the mean rate of ``t`` (:func:`sample_rate_of`)."""
        if self.fs is not None:
            return self.fs
        return sample_rate_of(self.t)

    @property
    def duration(self) -> float:
        """Span from first to last sample in seconds."""
        t = self.time
        return float(t[-1] - t[0]) if t.size else 0.0

    # -- access --------------------------------------------------------------
    def _check_names(self, names: Iterable[str]) -> list[str]:
        names = list(names)
        for name in names:
            if name not in self.channels:
                where = f" in {self.source}" if self.source else ""
                raise UnknownChannelError(
                    f"no channel '{name}'{where}; channels are: {', '.join(self.names)}"
                )
        return names

    def __getitem__(self, name: str) -> np.ndarray:
        self._check_names([name])
        return self.channels[name]

    def __contains__(self, name: object) -> bool:
        return name in self.channels

    def data(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Channels stacked as an array of shape (n_channels, n_samples)."""
        names = self.names if names is None else self._check_names(names)
        return np.stack([self.channels[n] for n in names])

    def unit(self, name: str) -> str:
        """Unit of a channel ('' when unknown)."""
        self._check_names([name])
        return self.units.get(name, "")

    def select(self, names: Sequence[str]) -> "Recording":
        """A recording holding only the named channels."""
        names = self._check_names(names)
        return self._replace(channels={n: self.channels[n] for n in names},
                             units={n: self.units[n] for n in names if n in self.units})

    def slice(self, start: int, stop: int | None = None) -> "Recording":
        """Samples ``start:stop`` of every channel (time base kept)."""
        sl = slice(start, stop)
        chans = {n: v[sl] for n, v in self.channels.items()}
        if self.t is not None:
            return self._replace(channels=chans, t=self.t[sl])
        first = range(self.n_samples)[sl]
        t0 = self.t0 + (first.start if len(first) else 0) / self.fs
        return self._replace(channels=chans, t0=t0)

    def window(self, start: float | None = None, stop: float | None = None) -> "Recording":
        """The samples from ``start`` to ``stop`` seconds after the first sample (both ends included).

        Parameters
        ----------
        start, stop : float, optional
            Seconds from the recording's first sample (``--start``/``--stop``);
            None keeps the record's own start or end. Time itself is not
            re-zeroed: the window's samples keep their time stamps.

        Raises
        ------
        InputError
            A start or stop that is negative or not finite, a stop not after
            the start, or a window with fewer than two samples.
        """
        if start is None and stop is None:
            return self
        for what, v in (("--start", start), ("--stop", stop)):
            if v is not None and not (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                                      and np.isfinite(v) and v >= 0):
                raise InputError(f"{what} is in seconds from the first sample and must be a finite number >= 0, "
                                 f"got {v!r}")
        if start is not None and stop is not None and not stop > start:
            raise InputError(f"--stop ({stop:g} s) must come after --start ({start:g} s)")
        t = self.time
        elapsed = t - t[0]
        keep = np.ones(t.size, dtype=bool)
        if start is not None:
            keep &= elapsed >= start
        if stop is not None:
            keep &= elapsed <= stop
        idx = np.flatnonzero(keep)
        if idx.size < 2:
            where = f" of {self.source}" if self.source else ""
            raise InputError(f"the window {start or 0:g} to {'the end' if stop is None else f'{stop:g} s'} holds "
                             f"{idx.size} sample(s) of the {self.duration:g} s record{where}; choose --start/--stop "
                             "within the record (seconds from its first sample)")
        return self.slice(int(idx[0]), int(idx[-1]) + 1)

    def _replace(self, **changes: Any) -> "Recording":
        kw = dict(channels=self.channels, t=self.t, fs=self.fs, t0=self.t0, units=self.units,
                  metadata=self.metadata, source=self.source, allow_nan=self.allow_nan, warnings=self.warnings)
        kw.update(changes)
        return Recording(**kw)

    def require_samples(self, n: int, what: str) -> None:
        """Raise :class:`TooFewSamplesError` unless at least ``n`` samples exist."""
        if self.n_samples < n:
            where = f" {self.source}" if self.source else ""
            raise TooFewSamplesError(
                f"recording{where} has {self.n_samples} samples but {what} needs at least {n}; record longer"
            )

    def __repr__(self) -> str:
        base = f"fs={self.fs:g} Hz" if self.fs is not None else f"t=[{self.time[0]:g} .. {self.time[-1]:g}] s"
        return f"Recording({len(self.channels)} channels x {self.n_samples} samples, {base}, channels={self.names})"
