"""The ``drift`` job: slow-drift bias correction of a recording, in one pass or continuing a saved state.

``senscal drift``, ``senscal batch drift`` and the demo call :func:`drift`;
the command line only parses, writes and prints.

Without ``state`` the job is today's ``senscal drift``: noise levels by
maximum likelihood, the augmented Kalman filter (or fixed-lag window, or RTS
smoother), CUSUM onsets.  With ``state`` (a path) it continues a
:class:`~senscal.drift.stream.DriftTracker`: the first file estimates the
levels and starts the state, later files keep them (``fit_levels`` asks for
a new estimate) and carry the filter on from the last sample of the
previous file, so daily files give the numbers of one pass over them all.
Reading and writing the state file stays with the caller; the result holds
the new state.

Examples
--------
>>> from senscal.jobs.drift import DriftOptions, drift                          # doctest: +SKIP
>>> res = drift("day1.csv", DriftOptions(preset="known", state="g.state.json"))  # doctest: +SKIP
>>> res.state.save("g.state.json")                                              # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, ClassVar, Mapping

import numpy as np

from senscal.diagnostics import named
from senscal.errors import DataError, InputError
from senscal.jobs._base import JobResult, Quantity, ReadOptions, source_name

__all__ = ["PRESETS", "BIAS_DYNAMICS", "DriftOptions", "DriftJobResult", "drift", "drift_setup_for",
           "start_tracker", "stream_document"]

PRESETS = ("redundant", "covariate", "known", "model")
BIAS_DYNAMICS = ("random_walk", "ramp")


@dataclass(frozen=True)
class DriftOptions(ReadOptions):
    """Options of the ``drift`` job (``senscal drift`` spells them ``--preset`` ...).

    Attributes
    ----------
    preset : {"redundant", "covariate", "known", "model"}
        Set-up preset (see docs/drift.md).
    channels : tuple of str, optional
        Measured channels (default: all but the covariate).
    trusted : tuple of str
        Channels that do not drift (redundant preset).
    covariate : str, optional
        Covariate channel the bias is linear in.
    model : str, optional
        YAML model file (preset ``model``).
    window : int, optional
        Fixed-lag window [samples].
    smooth : bool
        RTS smoother over the whole record (not with ``state``).
    false_alarm_rate : float
        Drift detector false alarms per hour per channel.
    signal, signal_tau, signal_mean :
        Model of the quantity; tau in s.
    signal_tau_known : bool
        The Gauss-Markov ``signal_tau`` is known.  False (default): with the
        comparison on, the result is averaged over the time constants the
        record allows (their profile likelihood as weight), so tau is in u.
    covariate_reference : float, optional
        Covariate value of zero covariate-linked bias.
    covariate_lag : float, optional
        Known first-order lag [s] between the covariate and the bias it
        drives (0: the bias follows the recorded covariate at once, e.g. a
        sensor that reads its own temperature).  None: not known; with the
        comparison on, the job averages the result over the lags the record
        holds (the lag's likelihood as weight), so the lag is in u, and
        names ``covariate-lag-uncertain`` when the data reject lag 0.
    bias_dynamics : {"random_walk", "ramp"}
    true_value : float
        Preset ``known``: the true reading [unit].
    compare : bool
        Fit the alternative models and warn when one has a lower AIC.
    state : str, optional
        Tracker state file (JSON or NPZ): continued when it exists, started
        otherwise.
    fit_levels : bool
        With ``state``: estimate the noise levels again on this file.
    levels_from_allan : bool
        Start the maximum-likelihood search from the Allan-deviation levels
        (:func:`senscal.drift.allan.drift_levels_from_allan`).
    flush : bool
        With ``state`` and a window: end of data, emit the samples the
        window still holds.
    time_column, fs, names, time_unit, skip_rows
        How to read the file (:class:`~senscal.jobs._base.ReadOptions`).
    """

    preset: str = "redundant"
    channels: tuple[str, ...] | None = None
    trusted: tuple[str, ...] = ()
    covariate: str | None = None
    model: str | None = None
    window: int | None = None
    smooth: bool = False
    false_alarm_rate: float = 1e-4
    signal: str = "random_walk"
    signal_tau: float | None = None
    signal_mean: float = 0.0
    signal_tau_known: bool = False
    covariate_reference: float | None = None
    covariate_lag: float | None = None
    bias_dynamics: str = "random_walk"
    true_value: float = 0.0
    compare: bool = True
    state: str | None = None
    fit_levels: bool = False
    levels_from_allan: bool = False
    flush: bool = False

    def __post_init__(self):
        super().__post_init__()
        for key in ("channels", "trusted"):
            v = getattr(self, key)
            if isinstance(v, str):
                v = tuple(s.strip() for s in v.split(",") if s.strip())
            if v is not None:
                object.__setattr__(self, key, tuple(v) or (None if key == "channels" else ()))
        if self.preset not in PRESETS:
            raise InputError(f"--preset must be one of {', '.join(PRESETS)}, got {self.preset!r}")
        if self.bias_dynamics not in BIAS_DYNAMICS:
            raise InputError(f"--bias-dynamics must be one of {', '.join(BIAS_DYNAMICS)}, got {self.bias_dynamics!r}")
        if self.window is not None and self.smooth:
            raise InputError("choose either --window or --smooth, not both")
        if self.state is not None and self.smooth:
            raise InputError("--smooth uses the whole record at once and cannot continue a --state; use --window")
        if self.state is None and (self.fit_levels or self.flush):
            raise InputError("--fit-levels and --flush are for --state runs (without a state the levels are always "
                             "estimated and every sample is output)")
        if self.covariate_lag is not None:
            if self.preset == "model":
                raise InputError("with --preset model give each covariate lag in the model file (lag: SECONDS), "
                                 "not --covariate-lag")
            if self.covariate is None:
                raise InputError("--covariate-lag is the lag of a covariate-linked bias: give --covariate NAME too")
            if not (math.isfinite(self.covariate_lag) and self.covariate_lag >= 0):
                raise InputError(f"--covariate-lag must be a time >= 0 s, got {self.covariate_lag}")
        if self.window is not None and (int(self.window) != self.window or self.window < 1):
            raise InputError(f"--window must be a whole number of samples >= 1, got {self.window}")
        if self.signal_tau_known and (self.signal != "gauss_markov" or self.signal_tau is None):
            raise InputError("--signal-tau-known asserts the time constant of a Gauss-Markov quantity: give "
                             "--signal gauss_markov --signal-tau SECONDS too")
        if self.signal_tau_known and self.preset not in ("redundant", "covariate"):
            raise InputError("--signal-tau-known is for the redundant and covariate presets (in a model file: "
                             "tau_known: true under signal)")

    @property
    def lag(self) -> int:
        """Fixed-lag window of a streamed run [samples] (0: the filter)."""
        return int(self.window or 0)


def drift_setup_for(rec, opts: DriftOptions):
    """The :class:`~senscal.drift.DriftSetup` a preset and its options describe for recording ``rec``."""
    from senscal.drift import load_model_yaml

    preset, covariate, trusted = opts.preset, opts.covariate, list(opts.trusted)
    if preset == "model":
        if opts.model is None:
            raise InputError("--preset model needs --model FILE.yaml")
        return load_model_yaml(opts.model)
    if opts.model is not None:
        raise InputError("--model is only used with --preset model")
    setup = _preset_setup(rec, opts, preset, covariate, trusted)
    if opts.covariate_lag is None:
        return setup
    return dataclasses.replace(setup, biases=tuple(
        dataclasses.replace(b, lag=float(opts.covariate_lag)) if b.covariate is not None else b
        for b in setup.biases))


def _preset_setup(rec, opts: DriftOptions, preset: str, covariate: str | None, trusted: list[str]):
    from senscal.drift import covariate_setup, known_setup, redundant_setup

    if covariate is not None and covariate not in rec:
        raise InputError(f"covariate channel '{covariate}' is not in the file (channels: {', '.join(rec.names)})")
    chans = list(opts.channels) if opts.channels else [c for c in rec.names if c != covariate]
    if preset == "known":
        if trusted:
            raise InputError("--trusted is for the redundant preset; with --preset known every channel's true "
                             "value is --true-value")
        return known_setup(chans, opts.true_value, bias_dynamics=opts.bias_dynamics, covariate=covariate,
                           covariate_reference=opts.covariate_reference)
    kw = dict(signal=opts.signal, signal_tau=opts.signal_tau, signal_mean=opts.signal_mean,
              covariate_reference=opts.covariate_reference, signal_tau_known=opts.signal_tau_known)
    if preset == "covariate":
        if covariate is None:
            raise InputError("--preset covariate needs --covariate NAME (the channel the bias follows)")
        if trusted:
            raise InputError("--trusted is for the redundant preset; the covariate preset has one sensor")
        if opts.bias_dynamics != "random_walk":
            raise InputError("--bias-dynamics is for the additive biases of the redundant and known presets; the "
                             "covariate preset has only a covariate-linked bias")
        if len(chans) != 1:
            raise InputError(f"--preset covariate corrects one sensor; choose it with --channels (got {', '.join(chans)})")
        return covariate_setup(chans[0], covariate, **kw)
    return redundant_setup(chans, trusted, covariate=covariate, bias_dynamics=opts.bias_dynamics, **kw)


def _arrays(rec, setup, where: str):
    """Measurements, time and covariates the set-up needs; ``where`` (``in FILE``) names the source in the error."""
    for c in list(setup.channels) + setup.covariates:
        if c not in rec:
            raise InputError(f"channel '{c}' is not {where} (channels: {', '.join(rec.names)})")
    return rec.data(list(setup.channels)), rec.time, {c: rec[c] for c in setup.covariates}


def _uncertain_levels(noise) -> list[str]:
    """Named warning when levels that a state will keep are poorly determined by the file they came from."""
    bad = [p.name for p in noise if p.estimated and (p.at_bound or (p.std is not None and p.std > 0.5 * p.value))]
    if not bad:
        return []
    return [named("drift-levels-uncertain", (
        f"the noise levels {', '.join(bad)} are poorly determined by this file (at a search bound or with a "
        "relative uncertainty above 50 %); the state keeps them and the stated bias uncertainties assume them: "
        "start the state on a longer file, or rerun a later file with --fit-levels"))]


def start_tracker(setup, y: np.ndarray, t: np.ndarray, cov: Mapping[str, np.ndarray], opts: DriftOptions,
                  state=None, *, progress: Callable[[], None] | None = None):
    """A tracker for this data: continued from ``state``, or started on it.

    A new state gets its noise levels by maximum likelihood on this data
    (Allan start values with ``levels_from_allan``), its prior and its
    covariate references from this data too.  A continued one must have the
    same set-up and window; with ``fit_levels`` its levels are estimated
    again on this data and the filter continues with them.

    Returns
    -------
    tracker : DriftTracker
    noise : tuple of NoiseParameter
        The levels in use (``estimated`` False when kept from the state).
    how : str
        ``started``, ``continued`` or ``refitted``.
    warnings : list of str
    """
    from senscal.drift import correct_drift
    from senscal.drift.allan import drift_levels_from_allan
    from senscal.drift.core import drift_prior
    from senscal.drift.estimate import NoiseParameter
    from senscal.drift.stream import DriftTracker, setup_to_dict

    warnings: list[str] = []
    if state is not None:
        if setup_to_dict(state.setup) != setup_to_dict(setup):
            raise DataError(f"the data do not continue the state: it was started with channels "
                            f"{', '.join(state.setup.channels)} and another set-up ({_setup_words(state.setup)}); "
                            f"give the same preset and options, or start a new state file")
        if state.lag != opts.lag:
            raise DataError(f"the state was started with --window {state.lag or 'none'}, not "
                            f"{opts.window or 'none'}; give the same window or start a new state file")
        if state.t_last is not None and t.size and not t[0] > state.t_last:
            raise DataError(f"the data do not continue the state: they start at t = {t[0]:.9g} s, not after its last "
                            f"sample t = {state.t_last:.9g} s (time going backwards: an old or repeated file?)")
    if state is None or opts.fit_levels:
        start = drift_levels_from_allan(setup, y, t) if opts.levels_from_allan else None
        # A state keeps the set-up it was started with: the comparison only warns.
        res = correct_drift(setup, y, t, cov, compare=opts.compare and state is None, start=start,
                            progress=progress, false_alarm_rate=opts.false_alarm_rate, select=False)
        noise = tuple(res.noise)
        levels = {p.name: p.value for p in noise}
        warnings += [w for w in res.warnings if not w.startswith("covariate-reference-defaulted")] \
            if state is not None else list(res.warnings)
        warnings += _uncertain_levels(noise)
    if state is None:
        refs = {}
        for name in setup.covariates:
            given = {b.reference for b in setup.biases if b.covariate == name} - {None}
            refs[name] = float(given.pop()) if given else float(np.mean(cov[name]))
        shift = setup.signal.mean if setup.signal.kind in ("gauss_markov", "known") else 0.0
        prior = drift_prior(setup, np.asarray(y, dtype=float) - shift, {k: cov[k] - refs[k] for k in refs},
                            float(t[-1] - t[0]))
        return DriftTracker(setup, levels, lag=opts.lag, prior=prior, references=refs), noise, "started", warnings
    if opts.fit_levels:
        return (DriftTracker.from_state(dataclasses.replace(state, levels=levels)), noise, "refitted", warnings)
    noise = tuple(NoiseParameter(name=k, value=float(v), std=None, estimated=False, at_bound=False)
                  for k, v in state.levels.items())
    return DriftTracker.from_state(state), noise, "continued", warnings


def _setup_words(setup) -> str:
    biases = ", ".join(b.name + ("" if b.dynamics == "random_walk" else f" ({b.dynamics})") for b in setup.biases)
    return f"signal {setup.signal.kind}; biases {biases or 'none'}"


def stream_document(file: str, preset: str, tracker, noise, how: str, n_samples: int, n_emitted: int,
                    loglik: float, warnings, state_path: str | None) -> dict[str, Any]:
    """The JSON document of a streamed (``--state``) run.

    ``channels``: per corrected channel the filtered ``bias`` and
    ``bias_std`` at the last sample (``t_s``) and each bias term's value and
    std; ``noise``: the levels used (``estimated`` False when kept from the
    state); ``state``: how it was used (``started`` / ``continued`` /
    ``refitted``), the samples held in the window, the totals.
    """
    cur = tracker.current()
    st = tracker.state
    chans = {}
    names = st.setup.state_names
    owners = st.setup.state_channels
    for i, c in enumerate(cur.channels):
        terms = {s: {"value": float(cur.state[j, 0]), "std": float(cur.state_std[j, 0])}
                 for j, s in enumerate(names) if owners[j] == c}
        chans[c] = {"bias": float(cur.bias[i, 0]), "bias_std": float(cur.u_bias[i, 0]), "t_s": float(cur.t[0]),
                    "terms": terms}
    return {
        "file": file, "preset": preset, "method": "window" if st.lag else "filter", "window": st.lag or None,
        "n_samples": int(n_samples), "n_output": int(n_emitted), "channels": chans,
        "noise": {p.name: {"value": p.value, "std": p.std, "estimated": p.estimated, "at_bound": p.at_bound}
                  for p in noise},
        "loglik": float(loglik),
        "state": {"path": state_path, "how": how, "t_last_s": st.t_last, "pending": int(st.buffer["t"].size),
                  "n_samples_total": int(st.n_samples), "n_output_total": int(st.n_emitted),
                  "references": dict(st.references)},
        "warnings": list(warnings),
    }


@dataclass(frozen=True)
class DriftJobResult(JobResult):
    """Bias estimates of one recording: a one-pass :class:`~senscal.drift.DriftResult` or a streamed chunk.

    Attributes
    ----------
    file : str
        The recording.
    preset : str
    units : dict of str to str
        Unit of each corrected channel.
    result : DriftResult or None
        The one-pass result (no ``state``).
    output : TrackerChunk or None
        The samples a streamed run made final (``state`` given).
    state : TrackerState or None
        The state to save after a streamed run.
    document : dict
        The JSON document (``senscal drift --json``).
    warnings : tuple of str
    """

    job: ClassVar[str] = "drift"

    file: str
    preset: str
    units: dict
    result: Any
    output: Any
    state: Any
    document: dict
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """Exactly ``senscal drift --json``."""
        return dict(self.document)

    def quantities(self) -> tuple[Quantity, ...]:
        """The final bias of each corrected channel, ``CHANNEL.bias`` (k=2)."""
        out = []
        for c, d in self.document["channels"].items():
            if d["bias"] is not None and d["bias_std"] is not None and math.isfinite(d["bias_std"]):
                out.append(Quantity(f"{c}.bias", d["bias"], d["bias_std"], self.units.get(c, "")))
        return tuple(out)

    def to_dataframe(self):
        """One row per corrected channel: final bias, u, U (k=2), onset and alarm times."""
        import pandas as pd

        rows = [{"channel": c, "bias": d["bias"], "u": d["bias_std"], "U": 2 * d["bias_std"],
                 "unit": self.units.get(c, ""), "onset_t": d.get("onset_t"), "alarm_t": d.get("alarm_t")}
                for c, d in self.document["channels"].items()]
        return pd.DataFrame(rows, columns=["channel", "bias", "u", "U", "unit", "onset_t", "alarm_t"])

    def columns(self) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, str]]:
        """Time, ``NAME_corrected`` / ``NAME_bias`` / ``NAME_bias_std`` columns and their units (for ``--out``)."""
        src = self.result if self.result is not None else self.output
        std = src.bias_std if self.result is not None else src.u_bias
        cols: dict[str, np.ndarray] = {}
        units: dict[str, str] = {}
        for i, c in enumerate(src.channels):
            cols[f"{c}_corrected"], cols[f"{c}_bias"], cols[f"{c}_bias_std"] = src.corrected[i], src.bias[i], std[i]
            u = self.units.get(c, "")
            units.update({f"{c}_corrected": u, f"{c}_bias": u, f"{c}_bias_std": u})
        return src.t, cols, units


def drift(source: Any, options: DriftOptions = DriftOptions(), *,
          progress: Callable[[], None] | None = None) -> DriftJobResult:
    """Estimate and remove slowly drifting biases of a recording.

    Parameters
    ----------
    source : str, Path or Recording
    options : DriftOptions
    progress : callable, optional
        Called once per likelihood evaluation (progress display).

    Returns
    -------
    DriftJobResult
    """
    from senscal.drift import correct_drift
    from senscal.drift.allan import drift_levels_from_allan
    from senscal.drift.stream import TrackerState
    rec = options.read(source, allow_nan=True, job="drift")
    name = source_name(source)
    setup = drift_setup_for(rec, options)
    y, t, cov = _arrays(rec, setup, f"in {name}")
    units = {c: rec.unit(c) or "" for c in setup.biased_channels}
    time_warnings = list(rec.warnings)  # the reading layer's time-base checks, for a drift record
    if options.state is None:
        start = drift_levels_from_allan(setup, y, t) if options.levels_from_allan else None
        res = correct_drift(setup, y, t, cov, window=options.window, smooth=options.smooth,
                            false_alarm_rate=options.false_alarm_rate, compare=options.compare, start=start,
                            progress=progress)
        warnings = tuple(res.warnings) + tuple(w for w in time_warnings if w not in res.warnings)
        res = dataclasses.replace(res, warnings=warnings)
        doc = {"file": name, "preset": options.preset, **res.summary()}
        return DriftJobResult(file=name, preset=options.preset, units=units, result=res, output=None, state=None,
                              document=doc, warnings=warnings)
    path = Path(options.state)
    state = TrackerState.load(path) if path.exists() else None
    tracker, noise, how, warnings = start_tracker(setup, y, t, cov, options, state, progress=progress)
    before = tracker.state.loglik
    out = tracker.update(y, t, cov)
    warnings += _stream_check(tracker.innovations, how, len(tracker.state.setup.state_names))
    if options.flush:
        tail = tracker.flush()
        out = _join(out, tail)
    warnings = tuple(warnings) + tuple(w for w in time_warnings if w not in warnings)
    doc = stream_document(name, options.preset, tracker, noise, how, t.size, out.n, tracker.state.loglik - before,
                          warnings, str(options.state))
    return DriftJobResult(file=name, preset=options.preset, units=units, result=None, output=out,
                          state=tracker.state, document=doc, warnings=warnings)


def _stream_check(innovations: np.ndarray, how: str, n_states: int) -> list[str]:
    """``model-inadequate`` when this file's innovations are not white noise of unit scale.

    The levels a state keeps were right for the file they came from; a drift
    that starts later (a ramp after a quiet first day) shows here first.
    """
    from senscal.drift import innovation_checks

    if innovations.shape[1] < 20:
        return []
    # A new state's first samples carry the prior's transient.
    check = innovation_checks(innovations, skip=min(innovations.shape[1] // 10, 5 * n_states) if how == "started" else 0)
    if check.adequate:
        return []
    return [named("model-inadequate", (
        f"this file's innovations are not white noise of unit scale (whiteness p = {check.whiteness_p:.1g}, mean "
        f"normalised innovation squared {check.nis:.3g}, p = {check.nis_p:.1g}): the noise levels "
        + ("kept from the state" if how == "continued" else "in use")
        + " no longer describe the data and the stated bias uncertainties are not to be trusted; rerun this file "
        "with --fit-levels (or another --bias-dynamics / model)"))]


def _join(a, b):
    """Two consecutive TrackerChunks as one."""
    return dataclasses.replace(a, **{k: np.concatenate([getattr(a, k), getattr(b, k)], axis=-1)
                                     for k in ("t", "corrected", "bias", "u_bias", "state", "state_std")})
