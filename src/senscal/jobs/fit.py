"""The ``fit`` job: least-squares sine fit of every (or the chosen) channel of a recording.

``senscal fit``, ``senscal batch fit``, the demo and the registry's ``--save``
all call :func:`fit`; the command line only parses and prints.

Examples
--------
>>> from senscal.jobs.fit import FitOptions, fit                 # doctest: +SKIP
>>> res = fit("sine.csv", FitOptions(freq=12.5))                 # doctest: +SKIP
>>> res.channels["ch1"].amplitude, res.channels["ch1"].u_amplitude  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

from senscal.diagnostics import named, warning_name
from senscal.errors import DataError, InputError, SenscalError
from senscal.jobs._base import JobResult, Quantity, ReadOptions, source_name

if TYPE_CHECKING:  # numpy and the engine (scipy.linalg) load when a fit runs, not for `senscal fit --help`
    import numpy as np

    from senscal.sinefit import SineFit

__all__ = ["NOISE_MODELS", "FitOptions", "FitResult", "fit", "fit_summary", "not_a_signal"]

NOISE_MODELS = ("auto", "white", "coloured")


@dataclass(frozen=True)
class FitOptions(ReadOptions):
    """Options of the ``fit`` job (``senscal fit`` spells them ``--freq`` ...).

    Attributes
    ----------
    channels : tuple of str, optional
        Channels to fit; None fits every channel.
    freq : float, optional
        Known frequency in Hz (three-parameter fit); None estimates it
        (four-parameter fit).
    harmonics : int
        Number of harmonics K (1 = the fundamental only).
    noise_model : {"auto", "white", "coloured"}
        How the uncertainties treat the residual (see :func:`senscal.fit_sine`).
    time_column, fs, names, time_unit, skip_rows
        How a file is read (:class:`~senscal.jobs._base.ReadOptions`).
    """

    channels: tuple[str, ...] | None = None
    freq: float | None = None
    harmonics: int = 1
    noise_model: str = "auto"

    def __post_init__(self):
        super().__post_init__()
        if self.noise_model not in NOISE_MODELS:
            raise InputError(f"--noise-model must be one of {', '.join(NOISE_MODELS)}, got {self.noise_model!r}")
        if self.channels is not None and not isinstance(self.channels, tuple):
            object.__setattr__(self, "channels", tuple(self.channels) or None)

    @property
    def method(self) -> str:
        """How the registry describes the fit."""
        return f"sine-fit, {self.harmonics} harmonic(s), frequency {'known' if self.freq else 'estimated'}"


def fit_summary(fit: SineFit) -> dict:
    """The JSON fields of one channel's fit (the ``senscal fit --json`` contract).

    ``phase_deg`` is the phase at t = 0 (the file's time origin);
    ``phase_centre_deg`` the phase at ``t_phase_centre_s``, the record's
    centre, which does not carry the frequency's lever arm.
    """
    import numpy as np

    d = {
        "frequency_hz": float(fit.frequency),
        "amplitude": float(fit.amplitude),
        "phase_deg": math.degrees(fit.phase),
        "offset": float(fit.offset),
        "u_frequency_hz": float(fit.u_frequency),
        "u_amplitude": float(fit.u_amplitude),
        "u_phase_deg": math.degrees(fit.u_phase),
        "u_offset": float(fit.u_offset),
        "residual_rms": float(fit.residual_rms),
        "snr_db": float(fit.snr_db),
        "n_samples": int(fit.n_samples),
        "phase_centre_deg": math.degrees(fit.phase_centre),
        "u_phase_centre_deg": math.degrees(fit.u_phase_centre),
        "t_phase_centre_s": float(fit.t_ref),
        "noise_model": str(fit.noise_model),
        "dof_effective": float(fit.dof_effective),
        "residual_lag1": float(fit.residual_lag1),
    }
    if np.isfinite(fit.jitter_rms):
        d["jitter_rms_s"] = float(fit.jitter_rms)
    if fit.thd is not None:
        d["thd_percent"] = 100.0 * float(fit.thd)
        d["harmonic_amplitudes"] = np.asarray(fit.harmonic_amplitudes).tolist()
        d["harmonic_phases_deg"] = np.degrees(fit.harmonic_phases).tolist()
    return d


def not_a_signal(y: np.ndarray) -> str | None:
    """Why a column cannot hold a sine (None when it might).

    NaN/inf cannot be fitted; a constant column has nothing to fit; a column
    that changes by the same step every sample is a sample counter or a ramp
    (a scope's ``Sample`` column), whose spectrum peaks at the lowest bin and
    whose fit fails with a misleading "record too short".
    """
    import numpy as np

    y = np.asarray(y, dtype=float)
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        more = f" (and {bad.size - 1} more)" if bad.size > 1 else ""
        kind = "NaN" if np.isnan(y[bad[0]]) else "inf"
        return f"it has {kind} in data row {bad[0] + 1}{more}; remove or interpolate the bad samples"
    if y.size and np.ptp(y) == 0.0:
        return f"it is constant ({y[0]:g}): there is no signal to fit"
    if y.size > 2:
        d = np.diff(y)
        if d[0] != 0.0 and np.ptp(d) <= 1e-9 * abs(d[0]):
            return (f"it rises by the same step ({d[0]:g}) every sample: a sample counter or ramp, not a signal; "
                    f"leave it out with --channel")
    return None


# Registry name suffix, JSON key (its u is "u_" + key), unit as the registry has always stored it.
_QUANTITIES = (("amplitude", "amplitude", ""), ("phase", "phase_deg", "deg"), ("offset", "offset", ""),
               ("frequency", "frequency_hz", "Hz"))


@dataclass(frozen=True)
class FitResult(JobResult):
    """The sine fits of a recording's channels.

    Attributes
    ----------
    file : str
        The recording (path, or the Recording's ``source``).
    channels : mapping of str to SineFit
        One fit per fitted channel, in the recording's order (SI units,
        phase in rad, standard uncertainties k=1).
    not_fitted : mapping of str to str
        Channels left out and why (constant, a sample counter, NaN, no sine ...).
    units : mapping of str to str
        Unit of each fitted channel ('' when the file gives none).
    warnings : tuple of str
        Named warnings (``coloured-noise``, ``channel-not-fitted``, ``clipped``,
        ``under-dithered``, ``inconsistent-blocks`` ...).
    instrument : mapping of str to InstrumentFindings
        Per fitted channel: what the samples show about the converter
        (clipping, quantisation) and what the fit did about it
        (:mod:`senscal.io.instrument`).
    consistency : mapping of str to BlockConsistency
        Per fitted channel: the refit on consecutive blocks of the record
        (:mod:`senscal.consistency`); absent for records too short for blocks.
    """

    job: ClassVar[str] = "fit"

    file: str
    channels: Mapping[str, SineFit]
    not_fitted: Mapping[str, str] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    instrument: Mapping[str, Any] = field(default_factory=dict)
    consistency: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal fit --json`` document: ``{"file", "channels": {NAME: {...}}, ["not_fitted"], "warnings"}``.

        Each channel also holds ``instrument`` (what the samples show about
        the converter and what was done about it) and ``consistency`` (the
        block refit) when they were computed.
        """
        chans = {}
        for c, f in self.channels.items():
            d = fit_summary(f)
            if c in self.instrument:
                d["instrument"] = self.instrument[c].to_dict()
            if c in self.consistency:
                d["consistency"] = self.consistency[c].to_dict()
            chans[c] = d
        doc: dict[str, Any] = {"file": self.file, "channels": chans}
        if self.not_fitted:
            doc["not_fitted"] = dict(self.not_fitted)
        doc["warnings"] = list(self.warnings)
        return doc

    def quantities(self) -> tuple[Quantity, ...]:
        """``<channel>.amplitude|phase|offset|frequency`` per channel (phase in deg, frequency in Hz).

        The frequency only when it was estimated: a known frequency (``freq``)
        has no uncertainty and the registry takes none without one.

        Amplitude and offset carry no unit, as the registry has always stored
        them (the channel's unit is in ``units`` and the kept result).
        """
        out = []
        for ch, f in self.channels.items():
            doc = fit_summary(f)
            for suffix, key, unit in _QUANTITIES:
                if suffix == "frequency" and not f.frequency_estimated:
                    continue  # a frequency given with --freq was not measured (u = 0): nothing to quote
                out.append(Quantity(f"{ch}.{suffix}", doc[key], doc[f"u_{key}"], unit))
        return tuple(out)

    def to_dataframe(self):
        """One row per fitted channel: the JSON fields of the fit (``phase_deg`` ...)."""
        import pandas as pd

        rows = [{"channel": c, **fit_summary(f)} for c, f in self.channels.items()]
        return pd.DataFrame.from_records(rows)


def fit(source: Any, options: FitOptions | None = None) -> FitResult:
    """Sine fit of a recording's channels.

    A channel that cannot be fitted (constant, a sample counter, NaN, no
    sinusoid ...) is left out with a ``channel-not-fitted`` warning naming
    it and the reason; the job fails only when no channel can be fitted.

    Parameters
    ----------
    source : str, Path or Recording
        The recording.
    options : FitOptions, optional
        Defaults: every channel, frequency estimated, one harmonic.

    Returns
    -------
    FitResult

    Raises
    ------
    SenscalError
        Unreadable file, unknown channel, a frequency above Nyquist, or no
        channel that could be fitted (one line, with the fix).
    """
    from senscal.sinefit import fit_sine

    options = FitOptions() if options is None else options
    # NaN in one channel should not stop the others: checked per channel below.
    rec = options.read(source, channels=options.channels, allow_nan=True, job="fit")
    name = source_name(source)
    from senscal.jobs._units import check_time_magnitude

    check_time_magnitude(rec, name)  # a time column x 1e300 failed inside the solver, not in one line
    chans = list(rec.names)
    y = rec.data(chans)
    freq, harmonics, noise_model = options.freq, options.harmonics, options.noise_model
    failed: dict[str, SenscalError] = {}
    reasons: dict[str, str] = {}
    for i, c in enumerate(chans):
        why = not_a_signal(y[i])
        if why is not None:
            reasons[c] = why
            failed[c] = DataError(f"channel {c!r} cannot be fitted: {why}")
    good = [i for i, c in enumerate(chans) if c not in failed]
    fits: dict[str, SineFit] = {}
    if freq is not None and good:
        try:
            res = fit_sine(y[good], rec.time, freq=freq, harmonics=harmonics, noise_model=noise_model)
            fits = {chans[i]: res.channel(j) for j, i in enumerate(good)}
        except SenscalError:
            fits = {}  # find out which channel: one by one below
    if not fits:
        for i in good:
            try:
                fits[chans[i]] = fit_sine(y[i], rec.time, freq=freq, harmonics=harmonics, noise_model=noise_model)
            except InputError as exc:
                if "Nyquist" in str(exc) and freq is not None:
                    # An argument error, the same for every channel; a time column in ms read as s is why, often.
                    suspect = [w for w in rec.warnings if w.startswith("time-unit-suspect")]
                    if suspect:
                        raise InputError(f"{exc} ({suspect[0]})") from None
                    raise
                failed[chans[i]] = exc
                reasons[chans[i]] = str(exc)
            except SenscalError as exc:
                failed[chans[i]] = exc
                reasons[chans[i]] = str(exc)
    if not fits:
        if len(failed) == 1:
            raise next(iter(failed.values()))
        detail = "; ".join(f"{c!r}: {r}" for c, r in reasons.items())
        raise DataError(f"no channel of {name} could be fitted ({detail})")
    instrument: dict[str, Any] = {}
    consistency: dict[str, Any] = {}
    extra: dict[str, list[str]] = {}
    for i, c in enumerate(chans):
        if c not in fits:
            continue
        fits[c], instrument[c], w_inst, keep = instrument_check(y[i], rec.time, fits[c], freq=freq,
                                                                harmonics=harmonics, noise_model=noise_model)
        blk = block_check(y[i], rec.time, fits[c], harmonics=harmonics, noise_model=noise_model, keep=keep)
        extra[c] = list(w_inst)
        if blk is not None:
            consistency[c] = blk
            bw = blk.warning()
            if bw:
                extra[c].append(bw)
    warnings = []
    for c, f in fits.items():
        for w in f.warnings:
            nm = warning_name(w)
            warnings.append(named(nm, f"channel {c!r}: {w[len(nm) + 2:]}") if nm else f"channel {c!r}: {w}")
        for w in extra.get(c, ()):
            nm = warning_name(w)
            warnings.append(named(nm, f"channel {c!r}: {w[len(nm) + 2:]}"))
    for c, r in reasons.items():
        warnings.append(named("channel-not-fitted", f"channel {c!r} was not fitted: {r}"))
    if freq is not None:
        # A --freq the data do not have is fitted without complaint; a free-frequency fit says so.
        from senscal.sinefit.freqcheck import frequency_mismatch

        warnings += [w for w in (frequency_mismatch(y[chans.index(c)], rec.time, freq, harmonics=harmonics, name=c)
                                 for c in fits) if w]
    ordered = {c: fits[c] for c in chans if c in fits}
    return FitResult(file=name, channels=ordered, not_fitted=dict(reasons),
                     units={c: rec.unit(c) for c in ordered},
                     instrument={c: instrument[c] for c in ordered},
                     consistency={c: consistency[c] for c in ordered if c in consistency},
                     warnings=_time_warnings(tuple(warnings), rec, y[good[0]] if good else None, freq,
                                             next(iter(ordered.values())).frequency,
                                             stated=options.time_unit is not None))


def _time_warnings(warnings: tuple[str, ...], rec, y, freq: float | None, fitted_hz: float, *,
                   stated: bool = False) -> tuple[str, ...]:
    """The fit's warnings plus the time-base ones: the reading layer's, and a ``--freq`` a unit factor off, or a
    free fit's frequency and rate both far below a calibration's (ms read as s; not when the user stated the
    time unit with ``--time-unit``: a file's header can be wrong, the user's own statement is taken)."""
    from senscal.io.plausibility import (check_fitted_frequency, check_known_frequency, dominant_frequency,
                                         merge_time_warnings)

    own: tuple[str, ...] = ()
    if freq is not None and y is not None:
        own = check_known_frequency(dominant_frequency(y, rec.time), freq)
    elif freq is None and rec.t is not None and not stated:
        # Only a time column can be in the wrong unit: --fs and a file's own rate are stated in Hz.
        own = check_fitted_frequency(rec.time, fitted_hz)
    return merge_time_warnings(merge_time_warnings(warnings, own), rec.warnings)


# A block must hold at least this many samples and periods: with fewer its fit is not the same
# estimator as the record's (its u rests on too few residuals and cycles).
_BLOCK_MIN_SAMPLES = 64
_BLOCK_MIN_PERIODS = 2.0
BLOCKS = 4


def instrument_check(y, t, fit: SineFit, *, freq: float | None = None, harmonics: int = 1,
                     noise_model: str = "auto"):
    """Inspect one channel for clipping and quantisation; refit without the clipped samples when needed.

    Parameters
    ----------
    y : ndarray, shape (N,)
        The channel's samples.
    t : ndarray, shape (N,)
        Time stamps in s.
    fit : SineFit
        The fit of all samples.
    freq, harmonics, noise_model
        As the job's options (a refit uses the same).

    Returns
    -------
    (fit, findings, warnings, keep)
        The fit to report (the refit of the samples away from the clip
        levels when clipping was found and could be handled), the
        :class:`~senscal.io.instrument.InstrumentFindings`, named warnings
        (``clipped`` when clipping was found and could not be handled,
        ``under-dithered``), and the mask of samples the reported fit used
        (None: all).

    Notes
    -----
    Clipping is judged against a fit of the samples *not* at the extremes
    (:func:`~senscal.io.instrument.clipping_test`); when found, the samples
    whose model value lies near a clip level are dropped
    (:func:`~senscal.io.instrument.clip_guard_mask`) and the rest refitted
    twice, so the selection follows the refit's model.  The refit's time
    base is not uniform: its u assumes white noise, and a correlated residual
    is still named.  Handled clipping is stated in the findings
    (``handled``), not as a warning: the result covers.
    """
    import dataclasses

    import numpy as np
    from scipy.special import ndtri

    from senscal.io.instrument import clip_guard_mask, clipping_test, inspect_channel, quantisation_effect
    from senscal.sinefit import fit_sine

    y = np.asarray(y, dtype=float)
    found = inspect_channel(y)
    warns: list[str] = []
    keep = None
    need = 8 * (2 * harmonics + 3)
    # One sample at each extreme is no pile-up (and at most one clipped sample): nothing to test.
    if found.n_samples > need and found.levels > 2 and max(found.n_at_low, found.n_at_high) >= 2:
        inner = (y > found.low) & (y < found.high)
        ct = None
        try:
            f_in = fit_sine(y[inner], t[inner], freq=freq if freq is not None else float(fit.frequency),
                            harmonics=harmonics, noise_model="white")
            model = f_in.evaluate(t)
            sigma = _local_sigma(y, t, inner, model, f_in)
            ct = clipping_test(y, model, sigma, lsb=found.lsb)
        except SenscalError:
            pass
        if ct is not None:
            found = dataclasses.replace(found, clipped_low=ct.clipped_low, clipped_high=ct.clipped_high,
                                        n_clipped=(found.n_at_low if ct.clipped_low else 0)
                                        + (found.n_at_high if ct.clipped_high else 0))
        if found.clipped:
            lo = found.low if found.clipped_low else None
            hi = found.high if found.clipped_high else None
            ends = " and ".join(f"{nm} {v:.6g} ({k} samples)" for nm, v, k, on in (
                ("low", found.low, found.n_at_low, found.clipped_low),
                ("high", found.high, found.n_at_high, found.clipped_high)) if on)
            refit, why = None, ""
            try:
                for _ in range(2):
                    keep = clip_guard_mask(y, model, sigma, low=lo, high=hi, lsb=found.lsb)
                    if int(keep.sum()) < need:
                        raise DataError(f"only {int(keep.sum())} samples lie away from the clip levels")
                    refit = fit_sine(y[keep], t[keep], freq=freq, harmonics=harmonics,
                                     noise_model="white" if noise_model == "auto" else noise_model)
                    model = refit.evaluate(t)
                    sigma = float(refit.residual_rms) * math.sqrt(refit.n_samples / max(refit.dof, 1))
            except SenscalError as exc:
                refit, why = None, str(exc)
            if refit is not None:
                fit = refit
                z = float(ndtri(1.0 - 0.5 / y.size))
                found = dataclasses.replace(found, handled=(
                    f"clipped at {ends}: fitted only the {int(keep.sum())} of {found.n_samples} samples whose model "
                    f"value stays {z:.2f} sigma or more inside the clip level (fewer than half a clipped sample "
                    f"expected among them); u is that fit's",))
            else:
                keep = None
                warns.append(named("clipped", (
                    f"the signal is clipped at {ends}: the converter saturated, which biases the amplitude and "
                    f"offset by more than their u, and the samples away from the clip level cannot be fitted "
                    f"alone ({why}); reduce the gain or widen the input range")))
    if found.lsb is not None and fit.residual_rms > 0:
        u_ref = float(min(fit.u_offset, fit.u_amplitude))
        qe = quantisation_effect(found.lsb, float(fit.residual_rms), u_ref)
        found = dataclasses.replace(found, under_dithered=qe.under_dithered, noise_lsb=qe.noise_lsb)
        if qe.under_dithered:
            warns.append(qe.warning())
    return fit, found, tuple(warns), keep


def _local_sigma(y, t, inner, model, fit: SineFit):
    """Noise standard deviation about ``model`` at each sample (unit of y).

    One number for constant variance; where the variance follows the phase
    (jitter is smallest at the crests, exactly where clipping is judged) the
    fitted variance of each sample, so the clipping test's tails are the crest's.
    """
    import numpy as np

    from senscal.sinefit.variance import phase_variance

    r = y[inner] - model[inner]
    sigma = float(np.sqrt(np.sum(r**2) / max(fit.dof, 1)))
    th = 2.0 * math.pi * float(fit.frequency) * t + float(fit.phase)
    pv = phase_variance(r, np.sin(th[inner]), np.cos(th[inner]))
    if not pv.significant:
        return sigma
    var = pv.mean + pv.cos2 * np.cos(2 * th) + pv.sin2 * np.sin(2 * th)
    return np.sqrt(np.maximum(var, 0.01 * max(pv.mean, 0.0)) * (r.size / max(fit.dof, 1)))


def block_check(y, t, fit: SineFit, *, harmonics: int = 1, noise_model: str = "auto", keep=None,
                blocks: int = BLOCKS):
    """Refit one channel on consecutive blocks at the record's frequency and test them against their u.

    Parameters
    ----------
    y, t : ndarray, shape (N,)
        Samples and time stamps (s).
    fit : SineFit
        The record's fit; its frequency is used in every block so that the
        phases at t = 0 are comparable.
    harmonics, noise_model
        As the job's.
    keep : ndarray of bool, optional
        Samples the record's fit used (clipping handled); the blocks use only them.
    blocks : int
        Number of blocks.

    Returns
    -------
    BlockConsistency or None
        None when the record is too short for blocks of at least 64 samples
        and 2 periods each.
    """
    import numpy as np

    from senscal.consistency import block_consistency, split_blocks
    from senscal.sinefit import fit_sine

    y = np.asarray(y, dtype=float)
    t = np.asarray(t, dtype=float)
    idx_all = np.arange(y.size) if keep is None else np.flatnonzero(keep)
    span = float(t[-1] - t[0]) if y.size > 1 else 0.0
    f0 = float(fit.frequency)
    if idx_all.size < blocks * _BLOCK_MIN_SAMPLES or span * f0 < blocks * _BLOCK_MIN_PERIODS:
        return None

    def one(idx):
        b = fit_sine(y[idx], t[idx], freq=f0, harmonics=harmonics, noise_model=noise_model)
        nu = float(b.dof_effective)
        return {"amplitude": (b.amplitude, b.u_amplitude, nu), "phase": (b.phase, b.u_phase, nu),
                "offset": (b.offset, b.u_offset, nu)}

    return block_consistency(one, [idx_all[ix] for ix in split_blocks(idx_all.size, blocks)], circular=("phase",))
