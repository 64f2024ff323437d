"""Monte-Carlo coverage of the sine fit's uncertainties (``fit_sine``, ``senscal fit``).

Every scenario simulates one 12.5 Hz sine per seed (amplitude 1 V, random
phase, offset 0.3 V, 2 s at 1 kHz: 25 periods, 2000 samples, noise 0.05 V per
sample, the ``simulate sine`` defaults) and fits it twice: with the frequency
given (three-parameter fit, all seeds in one batched call: the compiled path)
and with the frequency estimated (four-parameter fit, one call per seed).

Departures: AR(1) noise with rho = 0.5 and 0.9 (the noise density at
12.5 Hz is 2.8x and 12x the white level of the same variance; near 0 Hz 3x
and 19x), and a record far from t = 0 (t0 = 1e5 s), where the phase at t = 0
of the four-parameter fit is useless and must be named (``phase-origin-far``)
while the phase at the record centre must cover.

``warned`` of the coloured cases is the fraction of seeds whose fit switched
to the coloured-noise covariance (``coloured-noise`` warning); for the white
case it is the whiteness test's false-alarm rate (1 % by design).

Instrument departures (issue 25), each an option of the simulator
(:func:`senscal.simulate.sine.adc`, :func:`~senscal.simulate.sine.jittered_times`,
:func:`~senscal.simulate.sine.flicker_noise`):

* ``clip-*``: the ADC saturates at ``crest - sigma``, ``crest`` or
  ``crest + sigma`` (crest = 1.3 V).  The fit job's remedy
  (:func:`senscal.jobs.fit.instrument_check`: fit only the samples away from
  the clip level) must cover; ``warned`` is the fraction of seeds where the
  clipping was found (and handled).
* ``adc-*lsb``: an 8-bit ADC over +/-2 V (LSB 1/64 V) with analogue noise of
  0.1, 0.2, 0.3 LSB (under-dithered: ``under-dithered`` must fire) and 0.6
  LSB (dithered: must cover).
* ``jitter-*``: sample-clock jitter whose signal error ``A w delta`` is 1 or
  2 noise sigmas; the phase-dependent (sandwich) covariance and the
  amplitude's jitter correction must cover; ``warned`` =
  ``heteroscedastic-noise`` fired.
* ``flicker-10hz``, ``flicker-5hz``: 1/f noise crossing the white level at
  10 Hz (u(offset) 6x too small) or 5 Hz: the offset must be named
  (``low-frequency-noise`` from the fit, or ``inconsistent-blocks`` from the
  job's block refit), the others must cover.
"""

from __future__ import annotations

import math

import numpy as np

from senscal.diagnostics import has_warning
from senscal.simulate.sine import adc, ar1_noise, flicker_noise, jittered_times
from senscal.sinefit import fit_sine
from senscal.validation import CoverageRow, coverage_row

__all__ = ["SCENARIOS", "INSTRUMENT_SCENARIOS", "simulate_batch"]

JOB = "sinefit"
FS, N, FREQ, AMP, OFFSET, NOISE = 1000.0, 2000, 12.5, 1.0, 0.3, 0.05


def simulate_batch(n_seeds: int, seed0: int, *, rho: float = 0.0, t0: float = 0.0, noise: float = NOISE,
                   clip=None, lsb: float | None = None, jitter: float = 0.0, flicker: float = 0.0):
    """Records of the scenarios: ``(t, y, phase)``; y has shape (n_seeds, N), phase (n_seeds,) in rad.

    ``clip``, ``lsb``, ``jitter`` (s) and ``flicker`` (unit/sqrt(Hz) at 1 Hz)
    are the instrument departures of :func:`senscal.simulate.sine.simulate_sine`.
    """
    departed = clip is not None or lsb is not None or jitter or flicker or noise != NOISE
    key = [seed0, int(round(1000 * rho)), int(t0)]
    if departed:
        key += [7, int(round(1e6 * noise)), int(round(1e6 * (lsb or 0))), int(round(1e9 * jitter)),
                int(round(1e6 * flicker)), int(round(1e3 * (np.max(clip) if clip is not None else 0)))]
    rng = np.random.default_rng(key)
    phase = rng.uniform(-math.pi, math.pi, n_seeds)
    t = t0 + np.arange(N) / FS
    if not departed:
        y = AMP * np.sin(2 * math.pi * FREQ * t[None, :] + phase[:, None]) + OFFSET
        return t, y + ar1_noise(rng, (n_seeds, N), NOISE, rho), phase
    ts = jittered_times(rng, t, (n_seeds, N), jitter)
    y = AMP * np.sin(2 * math.pi * FREQ * ts + phase[:, None]) + OFFSET + ar1_noise(rng, (n_seeds, N), noise, rho)
    if flicker:
        y = y + flicker_noise(rng, (n_seeds, N), flicker, FS)
    return t, adc(y, clip=clip, lsb=lsb), phase


def _dphase(est, truth):
    return np.angle(np.exp(1j * (np.asarray(est) - np.asarray(truth))))


def _rows(case: str, n_seeds: int, seed0: int, rho: float, note: str) -> list[CoverageRow]:
    t, y, phase = simulate_batch(n_seeds, seed0, rho=rho)
    rows = []
    three = fit_sine(y, fs=FS, freq=FREQ)
    warned3 = [has_warning(three.channel(i).warnings, "coloured-noise") for i in range(n_seeds)]
    for q, est, u, tr in (("amplitude (3p)", three.amplitude, three.u_amplitude, AMP),
                          ("phase (3p)", _dphase(three.phase, phase), three.u_phase, 0.0),
                          ("offset (3p)", three.offset, three.u_offset, OFFSET)):
        rows.append(coverage_row(JOB, case, q, est, u, tr, warned=warned3, note=note))
    fits = [fit_sine(y[i], fs=FS) for i in range(n_seeds)]
    warned4 = [has_warning(f.warnings, "coloured-noise") for f in fits]

    def col(name):
        return np.array([getattr(f, name) for f in fits])

    for q, est, u, tr in (("amplitude (4p)", col("amplitude"), col("u_amplitude"), AMP),
                          ("phase (4p)", _dphase(col("phase"), phase), col("u_phase"), 0.0),
                          ("offset (4p)", col("offset"), col("u_offset"), OFFSET),
                          ("frequency (4p)", col("frequency"), col("u_frequency"), FREQ)):
        rows.append(coverage_row(JOB, case, q, est, u, tr, warned=warned4, note=note))
    return rows


def run_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """White Gaussian noise: the fit's own model."""
    return _rows("white", n_seeds, seed0, 0.0, "white noise; warned = false-alarm rate of the whiteness test")


def run_ar1_05(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """AR(1) noise, rho = 0.5."""
    return _rows("ar1-0.5", n_seeds, seed0, 0.5, "AR(1) noise rho 0.5; warned = switched to coloured")


def run_ar1_09(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """AR(1) noise, rho = 0.9 (the issue's 35-43 % coverage case)."""
    return _rows("ar1-0.9", n_seeds, seed0, 0.9, "AR(1) noise rho 0.9; warned = switched to coloured")


def run_ar1_09_white_model(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """AR(1) rho = 0.9 fitted with ``noise_model="white"`` forced: the issue's 35-43 % case must be named."""
    t, y, phase = simulate_batch(n_seeds, seed0, rho=0.9)
    note = "AR(1) rho 0.9, white covariance forced (the old behaviour): coloured-noise must fire"
    three = fit_sine(y, fs=FS, freq=FREQ, noise_model="white")
    warned = [has_warning(three.channel(i).warnings, "coloured-noise") for i in range(n_seeds)]
    return [coverage_row(JOB, "ar1-0.9-white-model", q, est, u, tr, warned=warned, expect="warn", note=note)
            for q, est, u, tr in (("amplitude (3p)", three.amplitude, three.u_amplitude, AMP),
                                  ("phase (3p)", _dphase(three.phase, phase), three.u_phase, 0.0),
                                  ("offset (3p)", three.offset, three.u_offset, OFFSET))]


def run_far_origin(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Four-parameter fit of a record starting at t0 = 1e5 s (white noise)."""
    t, y, phase = simulate_batch(n_seeds, seed0, t0=1e5)
    fits = [fit_sine(y[i], t) for i in range(n_seeds)]
    warned = [has_warning(f.warnings, "phase-origin-far") for f in fits]
    t_mid = 0.5 * (t[0] + t[-1])
    phase_mid = phase + 2 * math.pi * FREQ * t_mid
    col = lambda name: np.array([getattr(f, name) for f in fits])  # noqa: E731
    note = "t0 = 1e5 s; phase at t=0 must be named, phase at the record centre must cover"
    return [
        coverage_row(JOB, "far-origin", "phase at t=0 (4p)", _dphase(col("phase"), phase), col("u_phase"), 0.0,
                     warned=warned, expect="warn", note=note),
        coverage_row(JOB, "far-origin", "phase at centre (4p)", _dphase(col("phase_centre"), phase_mid),
                     col("u_phase_centre"), 0.0, note=note),
        coverage_row(JOB, "far-origin", "frequency (4p)", col("frequency"), col("u_frequency"), FREQ, note=note),
    ]


# Channels per batched three-parameter call: below the compiled kernel's threshold (2^18 values).
_CHUNK = 100


def _fit3(y):
    """Three-parameter fits of every row, in chunks: a list of one-channel SineFit."""
    out = []
    for c0 in range(0, y.shape[0], _CHUNK):
        f = fit_sine(y[c0:c0 + _CHUNK], fs=FS, freq=FREQ)
        out += [f.channel(i) for i in range(f.shape[0])] if f.shape else [f]
    return out


def _job_rows(case: str, y, t, phase, note: str, *, warning, expect: dict[str, str],
              detected=None, blocks: bool = False) -> list[CoverageRow]:
    """Fit every seed as ``senscal fit`` does (engine + instrument check), 3p and 4p; one row per quantity.

    ``warning``: the named warning (or tuple of names) whose firing is ``warned`` (None: ``detected``
    gives it, a callable of the instrument findings).  ``expect``: quantity prefix -> "cover" or
    "warn".  ``blocks``: also run the job's block consistency check (``inconsistent-blocks``).
    """
    from senscal.jobs.fit import block_check, instrument_check

    names = (warning,) if isinstance(warning, str) else tuple(warning or ())

    rows = []
    for label, fits0 in (("3p", _fit3(y)), ("4p", [fit_sine(y[i], fs=FS) for i in range(y.shape[0])])):
        fits, warned = [], []
        for i, f in enumerate(fits0):
            f2, found, warns, keep = instrument_check(y[i], t, f, freq=FREQ if label == "3p" else None)
            allw = tuple(f2.warnings) + tuple(warns)
            if blocks:
                blk = block_check(y[i], t, f2, keep=keep)
                allw += (blk.warning(),) if blk is not None and not blk.consistent else ()
            fits.append(f2)
            warned.append(any(has_warning(allw, nm) for nm in names) if names else bool(detected(found)))

        def col(name):
            return np.array([getattr(f, name) for f in fits])

        quants = [("amplitude", col("amplitude"), col("u_amplitude"), AMP),
                  ("phase", _dphase(col("phase"), phase), col("u_phase"), 0.0),
                  ("offset", col("offset"), col("u_offset"), OFFSET)]
        if label == "4p":
            quants.append(("frequency", col("frequency"), col("u_frequency"), FREQ))
        for q, est, u, tr in quants:
            rows.append(coverage_row(JOB, case, f"{q} ({label})", est, u, tr, warned=warned,
                                     expect=expect.get(q, "cover"), note=note))
    return rows


CREST = AMP + OFFSET


def _clip_run(level: float, name: str):
    def run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
        t, y, phase = simulate_batch(n_seeds, seed0, clip=(-10.0, level))
        note = (f"ADC saturates at {level:g} V (crest {CREST:g} V, noise {NOISE:g} V); fit job fits only the "
                "samples away from the clip level; warned = clipping found")
        return _job_rows(name, y, t, phase, note, warning=None, expect={}, detected=lambda f: f.clipped)
    run.__doc__ = f"Crest clipped at {level:g} V."
    return run


LSB_8BIT = 4.0 / 256   # 8-bit ADC over +/-2 V


def _adc_run(noise_lsb: float, name: str):
    def run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
        t, y, phase = simulate_batch(n_seeds, seed0, noise=noise_lsb * LSB_8BIT, lsb=LSB_8BIT)
        under = noise_lsb < 0.5
        note = (f"8-bit ADC (LSB {LSB_8BIT:.4g} V), analogue noise {noise_lsb:g} LSB; "
                + ("under-dithered must be named" if under else "dithered: must cover"))
        exp = {q: "warn" for q in ("amplitude", "phase", "offset")} if under else {}
        return _job_rows(name, y, t, phase, note, warning="under-dithered", expect=exp)
    run.__doc__ = f"Quantised by an 8-bit ADC, analogue noise {noise_lsb:g} LSB."
    return run


def _jitter_run(sigmas: float, name: str):
    def run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
        jit = sigmas * NOISE / (AMP * 2 * math.pi * FREQ)
        t, y, phase = simulate_batch(n_seeds, seed0, jitter=jit)
        note = (f"sample-clock jitter {jit * 1e6:.0f} us rms (A w jitter = {sigmas:g} noise sigma); "
                "warned = heteroscedastic-noise")
        return _job_rows(name, y, t, phase, note, warning="heteroscedastic-noise", expect={})
    run.__doc__ = f"Sample-clock jitter, signal error {sigmas:g} noise sigma."
    return run


def _flicker_run(corner_hz: float, name: str):
    def run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
        level = math.sqrt(2 * NOISE**2 / FS * corner_hz)
        t, y, phase = simulate_batch(n_seeds, seed0, flicker=level)
        note = (f"1/f noise crossing the white level at {corner_hz:g} Hz; u(offset) must be named "
                "(low-frequency-noise or inconsistent-blocks), the rest must cover")
        return _job_rows(name, y, t, phase, note, warning=("low-frequency-noise", "inconsistent-blocks"),
                         expect={"offset": "warn"}, blocks=True)
    run.__doc__ = f"1/f noise with a corner at {corner_hz:g} Hz."
    return run


_DEPARTED = {
    "clip-crest-1sigma": _clip_run(CREST - NOISE, "clip-crest-1sigma"),
    "clip-crest": _clip_run(CREST, "clip-crest"),
    "clip-crest+1sigma": _clip_run(CREST + NOISE, "clip-crest+1sigma"),
    "adc-0.1lsb": _adc_run(0.1, "adc-0.1lsb"),
    "adc-0.2lsb": _adc_run(0.2, "adc-0.2lsb"),
    "adc-0.3lsb": _adc_run(0.3, "adc-0.3lsb"),
    "adc-0.6lsb": _adc_run(0.6, "adc-0.6lsb"),
    "jitter-1sigma": _jitter_run(1.0, "jitter-1sigma"),
    "jitter-2sigma": _jitter_run(2.0, "jitter-2sigma"),
    "flicker-10hz": _flicker_run(10.0, "flicker-10hz"),
    "flicker-5hz": _flicker_run(5.0, "flicker-5hz"),
}

for _run in (run_white, run_ar1_05, run_ar1_09, run_ar1_09_white_model, run_far_origin):
    _run.full_seeds = 400
for _run in _DEPARTED.values():
    _run.full_seeds = 200

#: The instrument departures (issue 25): tests/sinefit/test_coverage_instrument.py runs them.
INSTRUMENT_SCENARIOS = tuple(_DEPARTED)

SCENARIOS = {"white": run_white, "ar1-0.5": run_ar1_05, "ar1-0.9": run_ar1_09,
             "ar1-0.9-white-model": run_ar1_09_white_model, "far-origin": run_far_origin, **_DEPARTED}
