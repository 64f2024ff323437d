"""Drift set-ups: the signal model, the biases, and the augmented state-space model.

A :class:`DriftSetup` says *what* drifts (which channels, additive or
covariate-linked, with which dynamics) in the field's words; the presets
build one so that a user need not write matrices.  :func:`augmented_model`
turns a set-up plus noise levels into the engine's
:class:`~senscal.kalman.StateSpaceModel` (patent step a), and
:func:`check_observable` refuses set-ups whose biases the data cannot
determine.

Units: every noise level is a standard deviation.  Random-walk levels are
rates, ``[unit / sqrt(s)]`` (a random walk of rate ``r`` wanders by
``r * sqrt(d)`` in ``d`` seconds); Gauss-Markov levels are stationary
standard deviations ``[unit]`` with a time constant ``tau`` [s].
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numba as nb
import numpy as np

from senscal._result import ResultMixin
from senscal.errors import FileFormatError, InputError, UnobservableError
from senscal.kalman import StateSpaceModel
from senscal.kalman._kernels import observability_gramian

__all__ = ["Bias", "SignalModel", "DriftSetup", "redundant_setup", "covariate_setup", "known_setup", "load_model_yaml",
           "augmented_model", "augmented_arrays", "lag_filter", "check_observable", "DYNAMICS", "SIGNAL_KINDS"]

#: Bias dynamics: random walk, first-order Gauss-Markov, and ``ramp`` (an
#: integrated random walk: the bias and its slope, the slope a random walk).
DYNAMICS = ("random_walk", "gauss_markov", "ramp")
#: Models of the measured quantity.
SIGNAL_KINDS = ("random_walk", "gauss_markov", "matrix", "known")


@dataclass(frozen=True)
class Bias(ResultMixin):
    """One slowly varying error term of a channel.

    Parameters
    ----------
    channel : str
        The measured channel it corrupts.
    covariate : str, optional
        Covariate channel: the bias is ``alpha_t * (c_t - reference)`` and
        the state is the coefficient ``alpha`` [unit / covariate unit]
        (patent claim 4); None for an additive bias ``b_t`` [unit].
    reference : float, optional
        Covariate value at which a covariate-linked bias is zero; None: the
        covariate's mean over the record.
    dynamics : {"random_walk", "gauss_markov", "ramp"}
        Bias model: random walk, first-order Gauss-Markov with ``tau``, or
        ``ramp``: two states, the bias and its slope, the slope a random
        walk (integrated random walk), so that a linear drift is followed
        without lag.
    level : float, optional
        Random walk: rate [unit/sqrt(s)]; Gauss-Markov: stationary standard
        deviation [unit]; ramp: random-walk rate of the slope
        [unit/s/sqrt(s)].  None: estimated by maximum likelihood.
    tau : float, optional
        Gauss-Markov time constant [s].
    lag : float, optional
        Covariate-linked bias only: the bias follows the covariate through a
        first-order lag of this time constant [s] (a sensor whose own
        temperature lags the probe that is recorded); None or 0: no lag.
    fit_lag : bool
        Estimate that time constant by maximum likelihood (noise parameter
        ``NAME_lag`` [s]); ``lag`` is then ignored.
    """

    channel: str
    covariate: str | None = None
    reference: float | None = None
    dynamics: str = "random_walk"
    level: float | None = None
    tau: float | None = None
    lag: float | None = None
    fit_lag: bool = False

    def __post_init__(self) -> None:
        if self.dynamics not in DYNAMICS:
            raise InputError(f"bias dynamics must be one of {', '.join(DYNAMICS)}, got {self.dynamics!r}")
        if self.dynamics == "gauss_markov" and not (self.tau is not None and self.tau > 0):
            raise InputError(f"the Gauss-Markov bias of {self.channel} needs a time constant tau > 0 in seconds")
        if self.level is not None and not self.level >= 0:
            raise InputError(f"the noise level of the bias of {self.channel} must be >= 0, got {self.level}")
        if self.reference is not None and not math.isfinite(self.reference):
            raise InputError(f"the covariate reference of the bias of {self.channel} must be a finite number, "
                             f"got {self.reference}")
        if (self.lag or self.fit_lag) and self.covariate is None:
            raise InputError(f"a covariate lag is for a covariate-linked bias; the bias of {self.channel} has no "
                             "covariate")
        if self.lag is not None and not (math.isfinite(self.lag) and self.lag >= 0):
            raise InputError(f"the covariate lag of the bias of {self.channel} must be >= 0 seconds, got {self.lag}")

    @property
    def lag_name(self) -> str | None:
        """Name of the estimated covariate lag [s], None when the lag is not estimated."""
        return self.name + "_lag" if self.fit_lag else None

    @property
    def name(self) -> str:
        """State name: ``B_bias`` or ``B_temperature_coefficient``."""
        return f"{self.channel}_bias" if self.covariate is None else f"{self.channel}_{self.covariate}_coefficient"

    @property
    def level_name(self) -> str:
        """Name of its noise parameter."""
        return self.name + {"random_walk": "_rate_std", "gauss_markov": "_std",
                            "ramp": "_slope_rate_std"}[self.dynamics]

    @property
    def state_names(self) -> list[str]:
        """Its states: the bias, and for a ramp also its slope [unit/s]."""
        return [self.name] + ([self.name + "_slope"] if self.dynamics == "ramp" else [])


@dataclass(frozen=True)
class SignalModel(ResultMixin):
    """Model of the measured quantity (the non-bias states).

    Parameters
    ----------
    kind : {"random_walk", "gauss_markov", "matrix", "known"}
        ``random_walk``: one state, rate ``level`` [unit/sqrt(s)];
        ``known``: the true value is ``mean`` at every sample (a sensor at
        rest, a gyro that does not turn); one state held at zero, no level;
        ``gauss_markov``: one state, ``mean + z`` with ``z`` first-order of
        time constant ``tau`` [s] and stationary std ``level`` [unit] (a
        model of the signal: its mean is known); ``matrix``: F, Q, H per
        sample as given.
    level, tau, mean : float, optional
        See ``kind``; ``level`` None means estimated.
    tau_known : bool
        ``gauss_markov`` only: the time constant is known (asserted by the
        user), so the job uses it as given.  False (default): ``tau`` is
        where the search starts; with the model comparison on, the result
        is averaged over the time constants the record allows, weighted by
        their profile likelihood (:func:`senscal.drift.core.correct_drift`).
    F, Q : ndarray, optional
        (ns, ns) per-sample transition and process noise (``matrix`` only).
    H : ndarray, optional
        (m, ns) gain of each channel to the states; default all ones
        (every channel measures the one quantity).
    """

    kind: str = "random_walk"
    level: float | None = None
    tau: float | None = None
    mean: float = 0.0
    F: Any = None
    Q: Any = None
    H: Any = None
    tau_known: bool = False

    def __post_init__(self) -> None:
        if self.kind not in SIGNAL_KINDS:
            raise InputError(f"signal model must be one of {', '.join(SIGNAL_KINDS)}, got {self.kind!r}")
        if self.kind == "gauss_markov" and not (self.tau is not None and self.tau > 0):
            raise InputError("a Gauss-Markov signal needs a time constant tau > 0 in seconds")
        if not isinstance(self.tau_known, bool):
            raise InputError(f"tau_known must be true or false, got {self.tau_known!r}")
        if self.tau_known and self.kind != "gauss_markov":
            raise InputError("a known signal time constant (tau_known) is for a gauss_markov signal")
        if not math.isfinite(self.mean):
            raise InputError(f"the signal mean must be a finite number, got {self.mean}")
        if self.kind == "matrix" and (self.F is None or self.Q is None or self.H is None):
            raise InputError("a matrix signal model needs F, Q and H")

    @property
    def n_states(self) -> int:
        return np.atleast_2d(np.asarray(self.F, dtype=float)).shape[0] if self.kind == "matrix" else 1

    @property
    def level_name(self) -> str | None:
        if self.kind in ("matrix", "known"):
            return None
        return "signal_rate_std" if self.kind == "random_walk" else "signal_std"


@dataclass(frozen=True)
class DriftSetup(ResultMixin):
    """What is measured, what may drift, and the known noise levels.

    Parameters
    ----------
    channels : sequence of str
        Measured channels, in the order of the measurement vector.
    signal : SignalModel
    biases : sequence of Bias
    noise_std : mapping of str to float, optional
        Measurement noise standard deviation of channels [unit]; channels
        left out are estimated.
    trusted : sequence of str
        Channels declared free of bias (documentation of the set-up).
    ar_noise : sequence of str
        Channels whose measurement noise is coloured: besides the white
        noise, a first-order autoregressive term (one state per channel,
        ``NAME_noise_ar``, stationary std ``NAME_noise_ar_std`` [unit] and
        time constant ``NAME_noise_ar_tau`` [s], both estimated).  It is
        noise, not bias: the corrected output keeps it.
    """

    channels: tuple[str, ...]
    signal: SignalModel = field(default_factory=SignalModel)
    biases: tuple[Bias, ...] = ()
    noise_std: Mapping[str, float] = field(default_factory=dict)
    trusted: tuple[str, ...] = ()
    ar_noise: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "channels", tuple(self.channels))
        object.__setattr__(self, "biases", tuple(self.biases))
        object.__setattr__(self, "trusted", tuple(self.trusted))
        object.__setattr__(self, "ar_noise", tuple(self.ar_noise))
        for c in self.ar_noise:
            if c not in self.channels:
                raise InputError(f"coloured (AR) noise given for {c}, which is not a measured channel")
        if len(set(self.ar_noise)) != len(self.ar_noise):
            raise InputError(f"a channel is repeated in the coloured-noise channels {list(self.ar_noise)}")
        object.__setattr__(self, "noise_std", dict(self.noise_std))
        if not self.channels:
            raise InputError("a drift set-up needs at least one measured channel")
        if len(set(self.channels)) != len(self.channels):
            raise InputError(f"channels are repeated in {list(self.channels)}")
        for b in self.biases:
            if b.channel not in self.channels:
                raise InputError(f"the bias of {b.channel} is on a channel that is not measured ({', '.join(self.channels)})")
            if b.covariate is not None and b.covariate in self.channels:
                raise InputError(f"covariate {b.covariate} is also a measured channel; a covariate must be a separate input")
        names = [b.name for b in self.biases]
        if len(set(names)) != len(names):
            raise InputError(f"the same bias is given twice among {names}")
        for c, s in self.noise_std.items():
            if c not in self.channels:
                raise InputError(f"noise level given for {c}, which is not a measured channel")
            if not s > 0:
                raise InputError(f"the noise standard deviation of {c} must be > 0, got {s}")
        if self.signal.kind == "matrix":
            H = np.atleast_2d(np.asarray(self.signal.H, dtype=float))
            if H.shape != (len(self.channels), self.signal.n_states):
                raise InputError(f"signal H must have shape ({len(self.channels)}, {self.signal.n_states}) "
                                 f"(channels x signal states), got {H.shape}")

    @property
    def covariates(self) -> list[str]:
        """Covariate channels the set-up reads, in first-use order."""
        out: list[str] = []
        for b in self.biases:
            if b.covariate is not None and b.covariate not in out:
                out.append(b.covariate)
        return out

    @property
    def biased_channels(self) -> list[str]:
        """Channels with at least one bias term (those that get corrected)."""
        return [c for c in self.channels if any(b.channel == c for b in self.biases)]

    @property
    def state_names(self) -> list[str]:
        ns = self.signal.n_states
        sig = ["signal"] if ns == 1 else [f"signal_{i}" for i in range(ns)]
        return sig + [s for b in self.biases for s in b.state_names] + [f"{c}_noise_ar" for c in self.ar_noise]

    @property
    def state_channels(self) -> list[str | None]:
        """The channel each state biases (None for signal and coloured-noise states)."""
        return ([None] * self.signal.n_states + [b.channel for b in self.biases for _ in b.state_names]
                + [None] * len(self.ar_noise))

    @property
    def n_bias_states(self) -> int:
        """Number of bias states (they follow the signal states; coloured-noise states come last)."""
        return sum(len(b.state_names) for b in self.biases)

    def level_names(self) -> list[str]:
        """Every noise parameter of the set-up (given or to estimate)."""
        out = [f"{c}_noise_std" for c in self.channels]
        if self.signal.level_name:
            out.append(self.signal.level_name)
        out += [b.level_name for b in self.biases]
        out += [b.lag_name for b in self.biases if b.lag_name]
        return out + [n for c in self.ar_noise for n in (f"{c}_noise_ar_std", f"{c}_noise_ar_tau")]

    def given_levels(self) -> dict[str, float]:
        """The noise parameters the user fixed."""
        out = {f"{c}_noise_std": float(s) for c, s in self.noise_std.items()}
        if self.signal.level_name and self.signal.level is not None:
            out[self.signal.level_name] = float(self.signal.level)
        for b in self.biases:
            if b.level is not None:
                out[b.level_name] = float(b.level)
        return out


def redundant_setup(channels: Sequence[str], trusted: Sequence[str] = (), *, covariate: str | None = None,
                    signal: str = "random_walk", signal_tau: float | None = None, signal_mean: float = 0.0,
                    bias_dynamics: str = "random_walk", bias_tau: float | None = None,
                    covariate_reference: float | None = None, signal_tau_known: bool = False) -> DriftSetup:
    """Preset ``redundant``: several sensors measure one quantity.

    Channels named in ``trusted`` have no bias; every other channel gets an
    additive bias, and a covariate-linked one too when ``covariate`` is
    given.  The quantity follows a random walk, or a Gauss-Markov process
    with known mean (``signal="gauss_markov"``).

    Parameters
    ----------
    channels : sequence of str
        The redundant sensors [same unit].
    trusted : sequence of str
        Reference sensors known not to drift.
    covariate : str, optional
        Covariate channel (e.g. temperature) for covariate-linked biases.
    signal, signal_tau, signal_mean :
        Model of the quantity (see :class:`SignalModel`); tau in s.
    signal_tau_known : bool
        The Gauss-Markov time constant is known (:attr:`SignalModel.tau_known`).
    bias_dynamics, bias_tau :
        Dynamics of the additive biases; tau in s.
    covariate_reference : float, optional
        Covariate value of zero covariate-linked bias (default: its mean).

    Returns
    -------
    DriftSetup
    """
    channels = list(channels)
    if len(channels) < 1:
        raise InputError("the redundant preset needs at least one channel")
    for c in trusted:
        if c not in channels:
            raise InputError(f"trusted channel {c} is not among the channels {', '.join(channels)}")
    biases: list[Bias] = []
    for c in channels:
        if c in trusted:
            continue
        biases.append(Bias(c, dynamics=bias_dynamics, tau=bias_tau))
        if covariate is not None:
            biases.append(Bias(c, covariate=covariate, reference=covariate_reference))
    return DriftSetup(channels=tuple(channels), signal=SignalModel(kind=signal, tau=signal_tau, mean=signal_mean,
                                                                   tau_known=signal_tau_known),
                      biases=tuple(biases), trusted=tuple(trusted))


def covariate_setup(channel: str, covariate: str, *, signal: str = "random_walk", signal_tau: float | None = None,
                    signal_mean: float = 0.0, covariate_reference: float | None = None,
                    signal_tau_known: bool = False) -> DriftSetup:
    """Preset ``covariate``: one sensor whose bias is linear in a covariate.

    ``y_t = s_t + alpha_t (c_t - c_ref) + v_t`` with ``alpha`` a slow random
    walk (patent claim 4).  A constant offset is not separable from the
    quantity with one sensor, so the bias is defined as zero at ``c_ref``.

    Parameters
    ----------
    channel : str
        The sensor.
    covariate : str
        The covariate channel (e.g. temperature in degC).
    signal, signal_tau, signal_mean :
        Model of the quantity (see :class:`SignalModel`).
    covariate_reference : float, optional
        Covariate value of zero bias (default: its mean over the record).
    signal_tau_known : bool
        The Gauss-Markov time constant is known (:attr:`SignalModel.tau_known`).

    Returns
    -------
    DriftSetup
    """
    return DriftSetup(channels=(channel,), signal=SignalModel(kind=signal, tau=signal_tau, mean=signal_mean,
                                                              tau_known=signal_tau_known),
                      biases=(Bias(channel, covariate=covariate, reference=covariate_reference),))


def known_setup(channels: Sequence[str], value: float = 0.0, *, bias_dynamics: str = "random_walk",
                bias_tau: float | None = None, covariate: str | None = None,
                covariate_reference: float | None = None) -> DriftSetup:
    """Preset ``known``: sensors whose true reading is known (zero or a constant).

    A gyro lying still reads the Earth rate (about zero for a MEMS gyro), a
    thermometer in a reference bath reads the bath: everything else is the
    sensor's own error.  Each channel gets an additive bias (random walk by
    default, ``ramp`` for a steady drift) plus, with ``covariate``, one
    linear in the covariate; the quantity is ``value`` at every sample, so
    even a constant offset is observable.

    Parameters
    ----------
    channels : sequence of str
        The sensors [unit].
    value : float
        Their common true reading [unit] (0 for a gyro at rest).
    bias_dynamics, bias_tau :
        Dynamics of the additive biases (see :class:`Bias`); tau in s.
    covariate : str, optional
        Covariate channel (e.g. the sensor's temperature).
    covariate_reference : float, optional
        Covariate value of zero covariate-linked bias (default: its mean;
        the additive bias absorbs the difference).

    Returns
    -------
    DriftSetup
    """
    channels = list(channels)
    if not channels:
        raise InputError("the known preset needs at least one channel")
    if not math.isfinite(value):
        raise InputError(f"the known true value must be a finite number, got {value}")
    biases: list[Bias] = []
    for c in channels:
        biases.append(Bias(c, dynamics=bias_dynamics, tau=bias_tau))
        if covariate is not None:
            biases.append(Bias(c, covariate=covariate, reference=covariate_reference))
    return DriftSetup(channels=tuple(channels), signal=SignalModel(kind="known", mean=float(value)),
                      biases=tuple(biases), trusted=())


def load_model_yaml(path: str | Path) -> DriftSetup:
    """Read preset ``model``: a YAML file describing the set-up.

    Layout (noise levels left out are estimated)::

        channels: [A, B, C]
        trusted: [A]                  # optional, documentation
        signal:                       # or {kind: random_walk, level: 0.01}, or
                                      # {kind: gauss_markov, tau: 200, tau_known: true}
          kind: matrix
          F: [[1.0]]                  # per sample
          Q: [[1.0e-6]]               # per sample, unit^2
          H: [[1], [1], [1]]          # channels x signal states
        noise_std: {A: 0.01, B: 0.02}  # unit
        biases:
          - {channel: B, dynamics: random_walk, level: 1.0e-5}      # unit/sqrt(s)
          - {channel: C, covariate: temperature, reference: 20.0}
          - {channel: C, dynamics: gauss_markov, tau: 86400, level: 0.05}
          - {channel: C, covariate: humidity, fit_lag: true}       # lag estimated
        ar_noise: [B]                 # coloured (AR(1)) noise on B

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    DriftSetup
    """
    import yaml

    from senscal.io.sidefiles import read_text

    path = Path(path)
    try:
        doc = yaml.safe_load(read_text(path, "model file"))  # one line for non-UTF-8 bytes
    except FileNotFoundError:
        raise FileFormatError(f"model file {path} does not exist") from None
    except yaml.YAMLError as exc:
        raise FileFormatError(f"model file {path} is not valid YAML ({str(exc).splitlines()[0]})") from None
    except FileFormatError:
        raise
    except (RecursionError, ValueError, TypeError, OverflowError) as exc:  # deep nesting, odd scalars
        raise FileFormatError(f"model file {path} cannot be read as a drift model ({type(exc).__name__})") from None
    except OSError as exc:
        raise FileFormatError(f"cannot read model file {path}: {exc.strerror or exc}") from None
    if not isinstance(doc, dict) or "channels" not in doc:
        raise FileFormatError(f"model file {path} must be a mapping with at least 'channels' (see docs/drift.md)")
    unknown = set(doc) - {"channels", "trusted", "signal", "noise_std", "biases", "ar_noise"}
    if unknown:
        raise FileFormatError(f"model file {path} has unknown keys {sorted(unknown)}; allowed: channels, trusted, "
                              "signal, noise_std, biases, ar_noise")
    try:
        sig = doc.get("signal") or {}
        if not isinstance(sig, dict):
            raise TypeError("signal must be a mapping")
        signal = SignalModel(**_numbers(sig, ("level", "tau", "mean"), "signal", path, arrays=("F", "Q", "H")))
        biases = []
        for b in doc.get("biases") or []:
            if not isinstance(b, dict):
                raise TypeError("each bias must be a mapping")
            biases.append(Bias(**_numbers(b, ("reference", "level", "tau", "lag"), "bias", path)))
        noise = doc.get("noise_std") or {}
        if not isinstance(noise, dict):
            raise TypeError("noise_std must be a mapping channel: standard deviation")
        noise = _numbers(noise, tuple(noise), "noise_std", path)
        return DriftSetup(channels=tuple(doc["channels"]), signal=signal, biases=tuple(biases),
                          noise_std=noise, trusted=tuple(doc.get("trusted") or ()),
                          ar_noise=tuple(doc.get("ar_noise") or ()))
    except TypeError as exc:
        raise FileFormatError(f"model file {path}: {exc}") from None


def _numbers(d: dict, keys: tuple, where: str, path, arrays: tuple = ()) -> dict:
    """``d`` with the numbers at ``keys`` (and number arrays at ``arrays``) checked: a string there is one line."""
    out = dict(d)
    for k in keys:
        v = out.get(k)
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise FileFormatError(f"model file {path}: {where} {k} must be a number, got {v!r}")
        out[k] = float(v)
    for k in arrays:
        if out.get(k) is not None:
            try:
                np.asarray(out[k], dtype=float)
            except (TypeError, ValueError):
                raise FileFormatError(f"model file {path}: {where} {k} must be a matrix of numbers, "
                                      f"got {out[k]!r}") from None
    return out


def _signal_blocks(sig: SignalModel, dt: np.ndarray, level: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Per-step (T, ns, ns) F and Q of the signal states."""
    T = dt.size
    if sig.kind == "matrix":
        F = np.atleast_2d(np.asarray(sig.F, dtype=float))
        Q = np.atleast_2d(np.asarray(sig.Q, dtype=float))
        return np.broadcast_to(F, (T,) + F.shape), np.broadcast_to(Q, (T,) + Q.shape)
    if sig.kind == "known":
        # The deviation from the known value: zero, held there.
        return np.ones((T, 1, 1)), np.zeros((T, 1, 1))
    return _scalar_dynamics(sig.kind, dt, level, sig.tau)


def _scalar_dynamics(kind: str, dt: np.ndarray, level: float | None, tau: float | None):
    """Exact discretisation of a scalar random walk / Gauss-Markov state."""
    lev = 0.0 if level is None else float(level)
    if kind == "ramp":
        # Integrated random walk: bias b' = s, slope s' = white noise of
        # density lev^2 (exact discretisation).
        F = np.zeros((dt.size, 2, 2))
        F[:, 0, 0] = F[:, 1, 1] = 1.0
        F[:, 0, 1] = dt
        Q = np.empty((dt.size, 2, 2))
        Q[:, 0, 0] = dt**3 / 3.0
        Q[:, 0, 1] = Q[:, 1, 0] = dt**2 / 2.0
        Q[:, 1, 1] = dt
        return F, lev**2 * Q
    if kind == "random_walk":
        F = np.ones_like(dt)
        Q = lev**2 * dt
    else:
        F = np.exp(-dt / tau)
        Q = lev**2 * -np.expm1(-2.0 * dt / tau)
    return F[:, None, None], Q[:, None, None]


def lag_filter(c: np.ndarray, dt: np.ndarray, tau: float) -> np.ndarray:
    """First-order lag of a sampled signal, started in equilibrium.

    Exact for an input that is linear between samples (first-order hold):
    ``y_k = a y_(k-1) + (1 - a - g) c_(k-1) + g c_k`` with ``a = exp(-dt/tau)``
    and ``g = 1 - tau (1 - a) / dt``.

    Parameters
    ----------
    c : ndarray, (T,)
        Input (e.g. a referenced temperature) [any unit].
    dt : ndarray, (T,) or (1,)
        Step into each sample [s] (``dt[0]`` unused); one value when uniform.
    tau : float
        Time constant [s]; 0 returns ``c``.

    Returns
    -------
    ndarray, (T,)
    """
    c = np.asarray(c, dtype=float)
    if not tau > 0:
        return c
    d = np.broadcast_to(np.asarray(dt, dtype=float), c.shape)
    r = d / tau
    a = np.exp(-r)
    # (1 - a) / r without cancellation when dt << tau.
    g = 1.0 + np.expm1(-r) / np.where(r > 0, r, 1.0)
    g = np.where(r > 0, g, 0.0)
    return _lag_kernel(c, a, g)


@nb.njit(cache=True)
def _lag_kernel(c, a, g):
    out = np.empty_like(c)
    if c.size == 0:
        return out
    out[0] = c[0]
    for k in range(1, c.size):
        out[k] = a[k] * out[k - 1] + (1.0 - a[k] - g[k]) * c[k - 1] + g[k] * c[k]
    return out


def _uniform_dt(dt: np.ndarray) -> np.ndarray:
    """The steps with dt[0] filled, reduced to one value when uniform."""
    dt = np.array(dt, dtype=float)
    T = dt.size
    if T > 1:
        dt[0] = dt[1]  # never used by the recursion; keeps the discretisation finite
    if T < 3 or np.ptp(dt) <= 1e-9 * np.abs(dt).max():
        return dt[:1]
    return dt


def augmented_arrays(setup: DriftSetup, dt: np.ndarray, levels: Mapping[str, float],
                     covariates: Mapping[str, np.ndarray] | None = None, *, x0: np.ndarray | None = None,
                     P0: np.ndarray | None = None, T: int | None = None):
    """The matrices of :func:`augmented_model` as raw stacks, without validation.

    For the likelihood loop of parameter estimation, which builds the model
    hundreds of times: ``F, Q`` are ``(1|T, n, n)``, ``H`` ``(1|T, m, n)``,
    ``R`` ``(1, m, m)``; ``dt`` as returned by :func:`_uniform_dt` (one value
    when uniform).  A coloured-noise state's prior variance is its
    stationary variance.

    Returns
    -------
    F, H, Q, R, x0, P0 : ndarray
    """
    T = dt.size if T is None else T
    m = len(setup.channels)
    ns = setup.signal.n_states
    nb_ = setup.n_bias_states
    na = len(setup.ar_noise)
    n = ns + nb_ + na
    Fs, Qs = _signal_blocks(setup.signal, dt, levels.get(setup.signal.level_name) if setup.signal.level_name else None)
    F = np.zeros((dt.size, n, n))
    Q = np.zeros((dt.size, n, n))
    F[:, :ns, :ns] = Fs
    Q[:, :ns, :ns] = Qs
    Hs = np.ones((m, 1)) if setup.signal.kind != "matrix" else np.atleast_2d(np.asarray(setup.signal.H, dtype=float))
    varying_h = bool(setup.covariates)
    H = np.zeros((T if varying_h else 1, m, n))
    H[:, :, :ns] = Hs
    j = 0
    for b in setup.biases:
        Fb, Qb = _scalar_dynamics(b.dynamics, dt, levels[b.level_name], b.tau)
        k = Fb.shape[-1]
        F[:, ns + j:ns + j + k, ns + j:ns + j + k] = Fb
        Q[:, ns + j:ns + j + k, ns + j:ns + j + k] = Qb
        j += k
        row = setup.channels.index(b.channel)
        # Only the bias itself is seen; a ramp's slope acts through F.
        col = ns + j - k
        if b.covariate is None:
            H[:, row, col] = 1.0
        else:
            if covariates is None or b.covariate not in covariates:
                raise InputError(f"covariate channel {b.covariate} is needed by the bias of {b.channel} but was not given")
            lag = levels[b.lag_name] if b.lag_name else (b.lag or 0.0)
            H[:, row, col] = lag_filter(covariates[b.covariate], dt, lag) if lag > 0 else covariates[b.covariate]
    x0 = np.zeros(n) if x0 is None else np.array(x0, dtype=float)
    P0 = np.eye(n) * 1e6 if P0 is None else np.array(P0, dtype=float)
    for i, c in enumerate(setup.ar_noise):
        a = ns + nb_ + i
        std, tau = levels[f"{c}_noise_ar_std"], levels[f"{c}_noise_ar_tau"]
        Fa, Qa = _scalar_dynamics("gauss_markov", dt, std, tau)
        F[:, a, a] = Fa[:, 0, 0]
        Q[:, a, a] = Qa[:, 0, 0]
        H[:, setup.channels.index(c), a] = 1.0
        # Stationary from the start: its first value is as uncertain as any.
        x0[a] = 0.0
        P0[a, :] = 0.0
        P0[:, a] = 0.0
        P0[a, a] = std**2
    R = np.diag([levels[f"{c}_noise_std"] ** 2 for c in setup.channels])[None]
    return F, H, Q, R, x0, P0


def augmented_model(setup: DriftSetup, dt: np.ndarray, levels: Mapping[str, float],
                    covariates: Mapping[str, np.ndarray] | None = None, *, x0: np.ndarray | None = None,
                    P0: np.ndarray | None = None) -> StateSpaceModel:
    """The augmented state-space model ``z = [x; b; a]`` (patent step a).

    ``F* = blockdiag(F, A, Phi)``, ``H*_t = [H, E_t, C]`` where column ``j``
    of ``E_t`` is the unit vector of the bias's channel (additive) or that
    vector times ``c_t - c_ref`` (covariate-linked, optionally through a
    first-order lag), ``C`` maps each coloured-noise state to its channel,
    ``Q* = blockdiag(Q, G, W)``, ``R = diag(noise_std^2)``.

    Parameters
    ----------
    setup : DriftSetup
    dt : ndarray, (T,)
        Step into each sample [s] (``dt[0]`` unused).
    levels : mapping
        Every noise parameter of ``setup.level_names()``.
    covariates : mapping of str to ndarray (T,), optional
        Covariate channels, already referenced (``c_t - c_ref``).
    x0, P0 : ndarray, optional
        Prior of the augmented state (default zeros, vague); a coloured-noise
        state's prior is its stationary distribution whatever is given.

    Returns
    -------
    StateSpaceModel
        Per-step matrices when the sampling is non-uniform or a covariate is
        used, constant otherwise.

    References
    ----------
    Patent CN102564486A (Shanghai Dianji University, 2012), step a and
    claim 4.
    """
    T = np.asarray(dt).size
    F, H, Q, R, x0_, P0_ = augmented_arrays(setup, _uniform_dt(dt), levels, covariates, x0=x0, P0=P0, T=T)
    if x0 is None and not setup.ar_noise:
        x0_ = None
    if P0 is None and not setup.ar_noise:
        P0_ = None
    # Constant matrices where possible: cheaper validation, and a
    # time-invariant model lets the engine take its steady-state path.
    F = F[0] if F.shape[0] == 1 else F
    Q = Q[0] if Q.shape[0] == 1 else Q
    H = H[0] if H.shape[0] == 1 else H
    if setup.signal.kind == "matrix":
        # A signal model from a file: its Q is the user's, checked in full.
        return StateSpaceModel(F=F, H=H, Q=Q, R=R[0], x0=x0_, P0=P0_)
    # Q is built of non-negative levels squared times blocks PSD for any step > 0
    # (its diagonal is still checked): no eigenvalue test per step (issue 30).
    return StateSpaceModel._built(F=F, H=H, Q=Q, R=R[0], x0=x0_, P0=P0_)


def check_observable(setup: DriftSetup, dt: np.ndarray, covariates: Mapping[str, np.ndarray] | None = None,
                     *, rtol: float = 1e-9) -> None:
    """Refuse a set-up whose biases cannot be told from the signal.

    Deterministic observability of the augmented pair ``(F*, H*_t)`` over
    the record: the information matrix ``W = sum_t Phi_t^T H_t^T H_t Phi_t``
    (``Phi_t`` the transition from the first sample), on up to 4000 samples
    spread over the record so that a slowly varying covariate counts, made
    scale-free by its diagonal.  An eigenvalue below ``rtol`` marks an
    unobservable direction; the states it involves are named.

    Parameters
    ----------
    setup : DriftSetup
    dt : ndarray, (T,)
        Steps [s].
    covariates : mapping, optional
        Referenced covariate channels (T,).
    rtol : float
        Relative eigenvalue threshold.

    Raises
    ------
    UnobservableError
        Naming the unobservable biases and what would make them observable.

    References
    ----------
    R. E. Kalman, "On the general theory of control systems" (1960);
    patent CN102564486A (the caution it skips: ``(F*, Phi*)`` must be
    observable).
    """
    dt = np.asarray(dt, dtype=float)
    T = dt.size
    # Coloured measurement noise is noise: it need not be observable, and its
    # fast-decaying states would only blur the test of the biases.
    setup = dataclasses.replace(setup, ar_noise=())
    # Unit noise levels: observability is structural.
    levels = {k: 1.0 for k in setup.level_names()}
    model = augmented_model(setup, dt, levels, covariates)
    n = model.n_states
    pick = np.unique(np.linspace(0, T - 1, min(T, 4000)).round().astype(int))
    # Step by step in compiled code (a ramp's transition changes with every
    # irregular step; 4000 matrix powers in Python cost more than that).
    W = observability_gramian(np.ascontiguousarray(model._F), np.ascontiguousarray(model._H), pick.astype(np.int64))
    names = setup.state_names
    if setup.signal.kind == "known":
        # The quantity is given: only the biases need to be observable.
        ns = setup.signal.n_states
        W, names, n = W[ns:, ns:], names[ns:], n - ns
    d = np.sqrt(np.diag(W))
    dead = [names[i] for i in range(n) if d[i] == 0]
    if not dead:
        Wn = W / np.outer(d, d)
        w, V = np.linalg.eigh(Wn)
        bad = w < rtol * w.max()
        if bad.any():
            Vb = V[:, bad]
            weight = np.sqrt((Vb**2).sum(axis=1))
            dead = [names[i] for i in range(n) if weight[i] > 1e-3]
    if not dead:
        return
    biases = [s for s in dead if s != "signal" and not s.startswith("signal_")]
    what = ", ".join(biases) if biases else ", ".join(dead)
    hints = []
    if not setup.trusted:
        hints.append("a trusted sensor that does not drift (--trusted)")
    if setup.signal.kind == "random_walk":
        hints.append("a model of the signal (e.g. a Gauss-Markov quantity with known mean, or a model YAML)")
    cov_dead = [b for b in setup.biases if b.covariate is not None and b.name in dead]
    if cov_dead:
        hints.append(f"a covariate that varies over the record ({', '.join(sorted({b.covariate for b in cov_dead}))} is constant or too smooth)")
    elif not setup.covariates:
        hints.append("a covariate the bias follows (--covariate)")
    raise UnobservableError(
        f"unobservable: {what} cannot be told apart from the measured quantity with this set-up "
        f"(every one of them could shift together with the signal); to make them observable give "
        + "; or ".join(hints))
