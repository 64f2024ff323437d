"""Heterodyne interferometer input (ISO 16063-41 style): demodulation to the quadrature pair.

A heterodyne interferometer gives one channel ``H = A(t) cos(2 pi f_c t + phi(t))`` with the Doppler phase
``phi = 4 pi s / lambda`` riding on a carrier (the frequency shift ``f_c``), optionally with the carrier
itself on a reference channel.  :func:`demodulate_heterodyne` mixes it down digitally and low-passes it::

    z[m] = sum_k h[k] 2 H[mD - k] exp(-j 2 pi f_c (mD - k) / fs)       (quadrature mixing + FIR, decimated by D)

so that ``z = A exp(j (phi + theta))``; with a reference, ``z conj(z_ref) / |z_ref|`` cancels the carrier's
phase, offset and drift; without one, the carrier's offset and linear drift (a linear and a quadratic phase)
are fitted jointly with the vibration and removed.  ``Re z, Im z`` are then an ideal quadrature pair (normalised to unit modulus, a limiter:
amplitude modulation does not reach the phase), and :func:`calibrate_heterodyne` runs the homodyne path (:func:`senscal.primary.calibrate_point`: ellipse, unwrap,
sine approximation, slices, fringe counting) on them.

The low-pass filter (Kaiser window, odd length, linear phase: its delay is removed exactly) is where the
demodulation can err, and its effect enters u (component ``demodulation_filter``):

* passband ripple and stopband leakage, both at most ``delta`` (the design's and the measured response's):
  the filtered envelope is ``z + e`` with ``rms(e) <= delta rms(z)`` (Parseval), so the phase error has an RMS of
  at most ``delta`` rad; its projection on the fundamental is a sine of at most ``sqrt(2) delta`` rad, i.e.
  ``sqrt(2) delta / phi_peak`` relative in magnitude and ``sqrt(2) delta / phi_peak`` rad in phase. The output
  channel passes the same filter: its gain at ``f`` is within ``1 +/- delta`` and its phase exact (the delay is an
  integer number of samples): its gain at the fitted frequency is computed from the taps and divided out.
  The envelope's bound is taken as rectangular (divided by sqrt 3).
* the envelope's band: the passband edge is at least ``1.1`` times the largest Doppler shift ``f_D`` measured
  from the carrier's analytic signal plus ``(2 + 5 beta^(1/3)) f`` with ``beta = f_D / f``: the Bessel
  sidebands ``J_k(beta)`` of a sinusoidal phase beyond ``k = beta`` follow the Airy function,
  ``J_(beta + x (beta/2)^(1/3)) ~ (2 / beta)^(1/3) Ai(x)``, under 1e-6 from ``x = 6``, so nothing of the envelope
  falls in the transition band.
* the noise: filtering and decimating would colour the noise where the transition band folds (the sine fit's
  white-noise u then misses the ratio ``kappa = 1 / (D sum h^2)`` of the noise density at low frequency to the
  white equivalent of its variance). The transition is centred on ``fs / (2 D)`` and power-complementary,
  ``|H(f)|^2 + |H(fs/D - f)|^2 = 1``, so the decimated noise stays white: ``kappa`` is 1 within 1 % (reported,
  tested). Without room to decimate (``D = 1``) a Kaiser low-pass cuts the noise beyond the image, and the
  sine fit's whiteness test switches to its coloured-noise model.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import DataError, InputError

__all__ = ["Demodulation", "demodulate_heterodyne", "calibrate_heterodyne"]

RIPPLE = 1e-6  # design ripple of the low-pass (pass and stop band), 120 dB


@dataclass(frozen=True)
class Demodulation(ResultMixin):
    """How a heterodyne signal was demodulated.

    Attributes
    ----------
    carrier_hz : float
        Nominal carrier given by the user (or the reference's), Hz.
    carrier_measured_hz : float
        Mean carrier of the signal (its analytic signal's phase slope; the reference's with one), Hz.
    carrier_offset_hz, carrier_drift_hz : float
        Offset of the measured carrier from the nominal one, and the linear drift removed over the record (0
        with a reference channel, which cancels both), Hz.
    doppler_max_hz : float
        Largest Doppler shift, the 0.999 quantile of the analytic signal's frequency deviation, Hz.
    passband_hz, stopband_hz : float
        Edges of the low-pass, Hz.
    taps, decimation : int
        Filter length (odd) and decimation factor.
    fs_out : float
        Sample rate of the demodulated pair, Hz.
    ripple : float
        Largest deviation of the filter's response from 1 in the passband and from 0 in the stopband (measured).
    kappa : float
        Noise density at low frequency over the white equivalent of the filtered noise's variance.
    reference : bool
        Demodulated against a reference carrier channel.
    trimmed_s : float
        Time cut at each end (the filter's half length), s.
    """

    carrier_hz: float
    carrier_measured_hz: float
    carrier_offset_hz: float
    carrier_drift_hz: float
    doppler_max_hz: float
    passband_hz: float
    stopband_hz: float
    taps: int
    decimation: int
    fs_out: float
    ripple: float
    kappa: float
    reference: bool
    trimmed_s: float

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


def _crossing_frequency(x: np.ndarray, fs: float) -> float:
    """Mean frequency (Hz) of a carrier from its first and last zero crossings and their count."""
    x = x - float(np.median(x))
    neg = np.signbit(x)
    idx = np.flatnonzero(neg[1:] != neg[:-1])
    if idx.size < 3:
        raise DataError("the carrier reference channel has no carrier (fewer than three zero crossings): name it "
                        "with --carrier-channel")
    tc = idx[[0, -1]] + x[idx[[0, -1]]] / (x[idx[[0, -1]]] - x[idx[[0, -1]] + 1])
    return 0.5 * (idx.size - 1) * fs / float(tc[1] - tc[0])


def _instantaneous(x: np.ndarray, fs: float) -> tuple[float, np.ndarray]:
    """Mean and instantaneous frequency (Hz) of a carrier from its analytic signal (FFT, 1 % cut at each end).

    The mean is the phase's least-squares slope; the instantaneous frequency the phase's difference per sample.
    """
    from scipy.fft import next_fast_len, rfft, ifft

    n = x.size
    nf = next_fast_len(n)
    spec = rfft(x - x.mean(), nf)
    full = np.zeros(nf, complex)
    full[:spec.size] = spec
    full[1:(nf + 1) // 2] *= 2.0
    if nf % 2 == 0:
        full[nf // 2] = spec[-1]
    za = ifft(full)[:n]
    cut = max(1, n // 100)
    za = za[cut:n - cut]
    dph = np.angle(za[1:] * np.conj(za[:-1]))
    f_inst = dph * fs / (2 * math.pi)
    return float(np.mean(f_inst)), f_inst


def _smooth_step(x: np.ndarray) -> np.ndarray:
    """A C-infinity step from 0 (x <= 0) to 1 (x >= 1)."""
    x = np.clip(x, 0.0, 1.0)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        a = np.where(x > 0, np.exp(-1.0 / np.where(x > 0, x, 1.0)), 0.0)
        c = np.where(x < 1, np.exp(-1.0 / np.where(x < 1, 1.0 - x, 1.0)), 0.0)
    return a / (a + c)


@functools.lru_cache(maxsize=8)
def _power_complementary(fs: float, d: int, b: float) -> np.ndarray:
    """Odd-length linear-phase low-pass for decimation by ``d``: 1 below ``fs/(2d) - b``, 0 above ``fs/(2d) + b``.

    Its zero-phase response in the transition is ``cos(pi/2 step(x))`` (``step`` a C-infinity step), so that
    ``|H(f)|^2 + |H(fs/d - f)|^2 = 1``: white noise stays white after the decimation.  Sampled densely,
    inverse-transformed, cut to ``16 fs / (2 b)`` taps under a Kaiser window (beta 6).
    """
    fo = fs / d
    nf = 1 << max(18, int(math.ceil(math.log2(64 * fs / b))))
    f = np.arange(nf // 2 + 1) * fs / nf
    resp = np.cos(0.5 * math.pi * _smooth_step((f - (fo / 2 - b)) / (2 * b)))
    full = np.fft.irfft(resp, nf)
    m = int(8 * fs / (2 * b))
    h = np.concatenate([full[-m:], full[:m + 1]]) * np.kaiser(2 * m + 1, 6.0)
    return h / h.sum()


@functools.lru_cache(maxsize=8)
def _kaiser_lowpass(fp: float, fst: float, fs: float, ripple: float) -> np.ndarray:
    """Odd-length Kaiser-window low-pass with passband edge ``fp``, stopband edge ``fst`` (Hz), DC gain 1."""
    a = -20.0 * math.log10(ripple)
    beta = 0.1102 * (a - 8.7) if a > 50 else (0.5842 * (a - 21) ** 0.4 + 0.07886 * (a - 21) if a > 21 else 0.0)
    dw = 2 * math.pi * (fst - fp) / fs
    n = int(math.ceil((a - 8.0) / (2.285 * dw))) + 1
    n += 1 - n % 2
    m = (n - 1) // 2
    fc = 0.5 * (fp + fst) / fs
    k = np.arange(-m, m + 1)
    h = 2 * fc * np.sinc(2 * fc * k) * np.kaiser(n, beta)
    return h / h.sum()


def _response_error(h: np.ndarray, fp: float, fst: float, fs: float) -> float:
    """Largest |H - 1| in [0, fp] and |H| in [fst, fs/2] of the zero-phase response (dense grid)."""
    nf = 1 << max(14, int(math.ceil(math.log2(16 * h.size))))
    H = np.abs(np.fft.rfft(h, nf))  # the magnitude of the linear-phase filter is its zero-phase response's
    f = np.arange(H.size) * fs / nf
    e_p = float(np.max(np.abs(H[f <= fp] - 1.0))) if np.any(f <= fp) else 0.0
    e_s = float(np.max(H[f >= fst])) if np.any(f >= fst) else 0.0
    return max(e_p, e_s)


def _fir_decimate(x: np.ndarray, h: np.ndarray, d: int) -> tuple[np.ndarray, int]:
    """``y[m] = sum_k h[k] x[m d + (L-1)/2 - k]`` for every m whose window lies inside x (centred, valid)."""
    from scipy.signal import oaconvolve, upfirdn

    L = h.size
    half = (L - 1) // 2
    # output j is sum_k h[k] x[j d - k]: direct (polyphase) for short filters, overlap-add FFT for long ones
    # (O(n log L) instead of O(n L / d): 3000 taps cost a tenth of the direct sum)
    y = upfirdn(h, x, 1, d) if L <= 64 * d else oaconvolve(x, h, mode="full")[::d]
    # centre sample of output j is j d - half; keep the windows inside the record
    j0 = -(-(L - 1) // d)
    j1 = (x.size - 1) // d
    y = y[j0:j1 + 1]
    return y, j0 * d - half


def demodulate_heterodyne(sig, fs: float, *, carrier_hz: float | None = None, reference=None,
                          freq: float | None = None, harmonics: int = 3, sign: int = 1,
                          ripple: float = RIPPLE) -> tuple[np.ndarray, np.ndarray, int, Demodulation, list[str]]:
    """Demodulate a heterodyne interferometer's carrier to an ideal quadrature pair.

    Parameters
    ----------
    sig : array_like, shape (N,)
        The carrier ``A cos(2 pi f_c t + phi(t))`` (any unit).
    fs : float
        Sample rate, Hz.
    carrier_hz : float, optional
        Nominal carrier frequency, Hz (required without ``reference``).
    reference : array_like, shape (N,), optional
        The carrier itself (the frequency shifter's drive): its phase, offset and drift cancel.
    freq : float, optional
        Vibration frequency, Hz (estimated from the local carrier frequency when omitted); sizes the band.
    harmonics : int
        Harmonics of ``freq`` fitted with the carrier drift (no reference).
    sign : {1, -1}
        -1 when the measuring beam's Doppler phase runs against the displacement (the other arm is shifted).
    ripple : float
        Design ripple of the low-pass (pass and stop band).

    Returns
    -------
    (i, q, start, Demodulation, warnings)
        The pair at ``fs / D`` (``i + j q = A exp(j phi)`` up to a constant phase), the original sample index
        of its first sample, the demodulation's record and named warnings.

    Raises
    ------
    InputError
        A carrier at or above the Nyquist frequency, or none given.
    DataError
        The carrier below twice the largest Doppler shift, or its image on the Doppler band.
    """
    return _demodulate(sig, fs, carrier_hz, reference, freq, harmonics, sign, ripple)[:5]


def _demodulate(sig, fs, carrier_hz, reference, freq, harmonics, sign, ripple):
    """:func:`demodulate_heterodyne`, also returning the low-pass it used (for the output channel)."""
    x = np.asarray(sig, float)
    fs = float(fs)
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        raise DataError("NaN or inf in the heterodyne channel: cut them out with --start/--stop")
    ref = None if reference is None else np.asarray(reference, float)
    if ref is not None and (ref.shape != x.shape or not np.all(np.isfinite(ref))):
        raise DataError("the carrier reference channel must be finite and as long as the heterodyne channel")
    if x.size < 1000:
        raise DataError(f"the heterodyne record holds {x.size} samples: the demodulation needs at least 1000 (and "
                        "several vibration periods); record longer")
    sd = float(np.std(x))
    if not sd > 0:
        raise DataError("the heterodyne channel is constant: no carrier; give the interferometer's carrier channel "
                        "with --heterodyne")
    if not math.isfinite(sd) or sd > 1e150:
        raise DataError("the heterodyne channel's values overflow the float range: rescale it")
    if carrier_hz is None and ref is None:
        raise InputError("a heterodyne input needs its carrier: give --carrier-hz F or --carrier-channel REF")
    if carrier_hz is not None and not (math.isfinite(carrier_hz) and carrier_hz > 0):
        raise InputError(f"--carrier-hz must be a positive frequency in Hz, got {carrier_hz!r}")
    if carrier_hz is not None and carrier_hz >= fs / 2:
        raise InputError(f"--carrier-hz {carrier_hz:g} Hz is at or above the Nyquist frequency {fs / 2:g} Hz: the "
                         "carrier aliases; record faster (or give the aliased carrier the samples show)")
    warnings: list[str] = []
    n = x.size
    f_meas, f_inst = _instantaneous(x, fs)
    if ref is not None:
        # the reference only places the band (its phase cancels in z conj(z_ref)): its zero crossings suffice
        f_ref = _crossing_frequency(ref, fs)
    nominal = float(carrier_hz) if carrier_hz is not None else f_ref
    if ref is not None:
        if carrier_hz is not None and abs(f_ref - carrier_hz) > 0.01 * carrier_hz:
            warnings.append(named("carrier-offset", f"the reference carrier runs at {f_ref:.6g} Hz, "
                                  f"{f_ref - carrier_hz:+.3g} Hz from --carrier-hz; the reference's was used"))
        f_mix = f_ref
    else:
        f_mix = f_meas
        if abs(f_meas - nominal) > 0.01 * nominal:
            warnings.append(named("carrier-offset", f"the carrier's mean frequency is {f_meas:.6g} Hz, "
                                  f"{f_meas - nominal:+.3g} Hz from --carrier-hz {nominal:g}: the measured carrier was "
                                  "used (check the frequency shifter, or give --carrier-channel)"))
    # largest Doppler shift; a carrier below it folds the band at zero frequency, which still shows a deviation
    # beyond f_c / 2 (the analytic signal's frequency runs through zero or negative)
    dev = np.abs(f_inst - f_mix)
    dop = float(np.quantile(dev, 0.999))
    if freq is None:
        # the instantaneous frequency oscillates at the vibration frequency: the peak of its spectrum
        m = max(1, f_inst.size // (1 << 16))
        fl = f_inst[::m]
        spec = np.abs(np.fft.rfft(fl - fl.mean()))
        spec[0] = 0.0
        span = fl.size * m / fs
        fv = max(float(np.argmax(spec)) / span, 1.0 / span)
    else:
        fv = float(freq)
    if f_mix < 2.0 * dop:
        raise DataError(f"the carrier ({f_mix:.6g} Hz) is below twice the largest Doppler shift ({dop:.4g} Hz): "
                        "the Doppler band reaches zero frequency; use a larger frequency shift or a smaller "
                        "vibration velocity")
    # the envelope's band: the largest Doppler shift and the Bessel sidebands beyond it (module docstring)
    beta = max(dop / fv, 1.0)
    fp = 1.1 * dop + fv * (2.0 + 5.0 * beta ** (1.0 / 3.0))
    # the mixing's image sits at -2 f_c (folded into the sampled band) with the same Doppler band
    d_img = abs(((-2.0 * f_mix + fs / 2) % fs) - fs / 2)
    # decimate to fs_out >= 2.2 fp, the transition band centred on fs_out / 2 and power-complementary there
    # (|H(f)|^2 + |H(fs_out - f)|^2 = 1): the noise folded by the decimation stays white (kappa = 1)
    # (and the phase advancing at most 0.3 turn a sample, well inside the unwrapping's limit)
    d = max(1, int(math.floor(min(fs / (2.2 * fp), 0.3 * fs / max(dop, 1e-300)))))
    fs_out = fs / d
    b = min(fs_out / 2 - fp, 0.1 * fs_out, d_img - fp - fs_out / 2)
    if d > 1 and b > 0.02 * fs_out:
        h = _power_complementary(fs, d, b)
        fst = fs_out / 2 + b
    else:
        # no room to decimate: a Kaiser low-pass between the envelope's band and the image (the noise beyond it
        # is cut, so the fit's coloured-noise model sees a band-limited noise)
        d, fs_out = 1, fs
        fst = min(d_img - fp, 3.0 * fp)
        if not fst > 1.05 * fp:
            raise DataError(f"the carrier's image at twice the carrier ({d_img:.4g} Hz from zero after mixing) lies "
                            f"on the Doppler band ({fp:.4g} Hz wide): choose a carrier nearer fs/4 ({fs / 4:g} Hz) "
                            "or record faster")
        h = _kaiser_lowpass(fp, fst, fs, ripple)
    delta = _response_error(h, fp, fst, fs)
    k = np.arange(n)
    # exp(-j 2 pi f k / fs) with the phase reduced modulo one turn first (exact for long records)
    lo = np.exp(-2j * math.pi * ((f_mix / fs * k) % 1.0))
    z, start = _fir_decimate(2.0 * x * lo, h, d)
    if z.size < 64:
        raise DataError(f"the record ({x.size} samples) leaves {z.size} demodulated samples after the low-pass "
                        f"({h.size} taps, decimation {d}): record longer (several vibration periods)")
    drift_hz = 0.0
    if ref is not None:
        zr, _ = _fir_decimate(2.0 * ref * lo, h, d)
        z = z * np.conj(zr) / np.maximum(np.abs(zr), 1e-300)
    if sign < 0:
        z = np.conj(z)
    if ref is None:
        # carrier offset left by the crossings' estimate and a linear carrier drift: a linear and a quadratic
        # phase, fitted jointly with the vibration (and its harmonics) and taken out of z
        ph = np.unwrap(np.angle(z))
        t = (np.arange(z.size) - 0.5 * (z.size - 1)) / fs_out
        if freq is None:
            # the spectrum's peak is only good to 1/T: refine the vibration frequency by the four-parameter fit
            # of the phase with the quadratic taken out (a wrong frequency would leak into the carrier's terms)
            from senscal.errors import SenscalError
            from senscal.sinefit import fit_sine

            try:
                fv = float(fit_sine(ph - np.polyval(np.polyfit(t, ph, 2), t), fs=fs_out, harmonics=1).frequency)
            except SenscalError:
                pass
        w = 2 * math.pi * fv
        cols = [np.ones_like(t), t, t * t]
        for kk in range(1, max(1, int(harmonics)) + 1):
            cols += [np.sin(kk * w * t), np.cos(kk * w * t)]
        X = np.column_stack(cols)
        coef = np.linalg.solve(X.T @ X, X.T @ ph)
        z = z * np.exp(-1j * (coef[1] * t + coef[2] * t * t))
        drift_hz = float(coef[2] * t[-1] * 2 / math.pi)  # change of 2 c2 t / (2 pi) over the record
        f_mix = f_mix + float(coef[1]) / (2 * math.pi)
    dem = Demodulation(carrier_hz=nominal, carrier_measured_hz=float(f_mix), carrier_offset_hz=float(f_mix - nominal),
                       carrier_drift_hz=drift_hz, doppler_max_hz=dop, passband_hz=fp, stopband_hz=fst,
                       taps=int(h.size), decimation=d, fs_out=fs_out, ripple=delta,
                       kappa=float(1.0 / (d * float(h @ h))), reference=ref is not None,
                       trimmed_s=float((h.size - 1) / 2 / fs))
    return z.real.copy(), z.imag.copy(), int(start), dem, warnings, h


def calibrate_heterodyne(sig, output, fs: float, *, carrier_hz: float | None = None, reference=None,
                         freq: float | None = None, sign: int = 1, harmonics: int = 3, **kwargs):
    """Sensitivity and phase of an accelerometer against a heterodyne interferometer (ISO 16063-41 style).

    Parameters
    ----------
    sig : array_like, shape (N,)
        The interferometer's carrier channel.
    output : array_like, shape (N,)
        The accelerometer's output.
    fs : float
        Sample rate, Hz.
    carrier_hz : float, optional
        Nominal carrier, Hz (or give ``reference``).
    reference : array_like, optional
        Reference carrier channel.
    freq : float, optional
        Excitation frequency, Hz.
    sign : {1, -1}
        Direction of the Doppler phase (see :func:`demodulate_heterodyne`).
    harmonics : int
    **kwargs
        Passed to :func:`senscal.primary.calibrate_point` (``wavelength_nm``, ``drift``, ``slices``, type B u ...).

    Returns
    -------
    (PrimaryPoint, Demodulation)
        The point's budget has the component ``demodulation_filter``; ``frequency_hz`` etc. as for the
        homodyne path, its phases refer to the common (trimmed, decimated) time base of both channels.
    """
    from senscal.primary.core import calibrate_point, check_wavelength

    check_wavelength(kwargs.get("wavelength_nm", 632.8))
    out = np.asarray(output, float)
    if out.shape != np.shape(sig) or out.ndim != 1:
        raise InputError("the heterodyne and output channels must be one-dimensional and of equal length")
    if not np.all(np.isfinite(out)):
        raise DataError("NaN or inf in the output samples: cut them out with --start/--stop")
    if not np.ptp(out) > 0:
        raise DataError("the output channel is constant: name the accelerometer's channel with --output")
    i_sig, q_sig, start, dem, warns, h = _demodulate(sig, fs, carrier_hz, reference, freq, harmonics, sign, RIPPLE)
    o, _ = _fir_decimate(out, h, dem.decimation)
    # a limiter: the digital pair has no offsets, gain ratio or quadrature error, so the ellipse fit must see the
    # unit circle; the carrier's amplitude (modulation, radial noise) would otherwise enter the Heydemann fit as
    # a spurious ellipse (10 % AM: the 5 kHz sensitivity covered 81 % over 200 seeds, with u twice too large)
    r = np.hypot(i_sig, q_sig)
    if not np.all(r > 0):
        raise DataError("the demodulated carrier vanishes in places (no signal): check the heterodyne channel")
    i_sig, q_sig = i_sig / r, q_sig / r
    try:
        p = calibrate_point(i_sig, q_sig, o, dem.fs_out, freq=freq, harmonics=harmonics, **kwargs)
    except DataError as exc:
        if "sign is flipped" in str(exc):
            raise DataError(f"the output is 180 deg from the acceleration: the Doppler phase runs against the "
                            "displacement (give --carrier-sign -1: the other arm carries the frequency shift), or "
                            "the output is inverted (then --no-sign-check)") from None
        raise
    lam = kwargs.get("wavelength_nm", 632.8) * 1e-9
    phi_peak = 4 * math.pi * p.displacement_m / lam
    # the output passed the filter: its gain at the fitted frequency is known exactly (the phase is exactly 0,
    # the filter being symmetric), so it is divided out rather than bounded
    kk = np.arange(h.size) - (h.size - 1) / 2
    gain = float(h @ np.cos(2 * math.pi * p.frequency_hz / fs * kk))
    # the envelope's phase error: at most sqrt(2) delta rad on the fundamental (module docstring), rectangular
    b = math.sqrt(2.0) * dem.ripple / max(phi_peak, 1e-300)
    budget = dict(p.budget)
    budget["demodulation_filter"] = {"type": "B", "u_rel": b / math.sqrt(3.0), "u_phase_deg": math.degrees(b / math.sqrt(3.0))}
    ur = math.sqrt(sum(v["u_rel"] ** 2 for v in budget.values()))
    up = math.sqrt(sum(v["u_phase_deg"] ** 2 for v in budget.values()))
    sens = p.sensitivity / gain
    p = dataclasses.replace(p, sensitivity=sens, u_sensitivity=abs(sens) * ur, u_phase_deg=up, budget=budget,
                            warnings=tuple(dict.fromkeys([*warns, *p.warnings])))
    return p, dem
