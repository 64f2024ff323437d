"""Coverage scenarios of ``senscal shock`` (ISO 16063-22 comparison, ISO 16063-13 laser primary).

Every seed simulates three records, one half-sine pulse each: 0.05 ms at
1e5 m/s^2 (4 MS/s), 1 ms at 5000 m/s^2 (200 kS/s) and 10 ms at 500 m/s^2
(100 kS/s), 200 samples a pulse and more.  Comparison: the reference's stated
sensitivity has u = 0.05 % (small, so that the noise terms are tested too) and its true value is drawn from it, output and
reference noise 1e-3 of their peaks (60 dB).  Quantities: the peak-ratio
sensitivity (truth: the noise-free peak ratio, which is the sensitivity S
unless the sensor's resonance shapes the pulse) and the transfer function's
magnitude and phase at the 3rd and 7th of its 8 frequencies (truth:
``S G(f)``, G the sensor's resonance).

Cases (comparison): ``white``; ``noise`` (3x the noise, AR(1) 0.8: must
cover); ``filter`` (the stated low-pass at 5 / T on both channels: must
cover); ``zero-shift`` (1 % of the peak, growing with the pulse: corrected;
the peak ratios must raise ``zero-shift``, whose model doubt, half the shift
rectangular, dominates and over-covers; the transfer function must cover); ``ringing`` (resonance 30 kHz, Q 30: the 0.05 and 1 ms pulses'
peak ratios must raise ``shock-ringing``, the sharp corners of a half-sine ringing the resonance
about the peak; everything else must cover).  Primary:
``primary-velocity`` (laser velocity, noise 1e-3 of the velocity change) and
``primary-displacement`` (laser displacement, 1 nm noise), both with the
stated low-pass at 10 / T: must cover.
"""

from __future__ import annotations

import math

import numpy as np

from senscal.validation import CoverageRow, coverage_row

__all__ = ["SCENARIOS", "PULSES", "one_seed", "true_peak_ratio"]

JOB = "shock"
# (duration ms, peak m/s^2, sample rate Hz)
PULSES = ((0.05, 1e5, 4e6), (1.0, 5000.0, 2e5), (10.0, 500.0, 1e5))
U_REF = 5e-4
TF_INDEX = (2, 6)


def true_peak_ratio(tr: dict, fs: float) -> float:
    """Noise-free peak ratio of the simulated pulse (the shock sensitivity ISO 16063-22 defines)."""
    from senscal.simulate.shock import simulate_shock

    kw = {k: tr[k] for k in ("duration_ms", "sensitivity", "resonance_hz", "resonance_q")}
    rec, _ = simulate_shock(**kw, peak=1.0, fs=fs, reference_sensitivity=1.0, reference_noise_rel=0.0,
                            output_noise_rel=0.0, seed=0)
    r, o = rec.channels["ref"], rec.channels["out"]
    return float(o[np.argmax(np.abs(o))] / r[np.argmax(np.abs(r))])


def one_seed(seed: int, sim_kw: dict, *, mode: str = "comparison", laser: str = "velocity",
             cutoff_per_t: float | None = None, warn: str | None = None):
    """Per pulse duration: quantity -> (estimate, u, truth, warned); None for a refused record."""
    from senscal.diagnostics import has_warning
    from senscal.shock import shock_pulses
    from senscal.simulate.shock import resonance_response, simulate_shock

    out = {}
    for i, (T, peak, fs) in enumerate(PULSES):
        rec, tr = simulate_shock(duration_ms=T, peak=peak, fs=fs, mode=mode, laser=laser,
                                 u_reference_rel=U_REF if mode == "comparison" else 0.0, seed=seed * 8 + i, **sim_kw)
        c = rec.channels
        cutoff = None if cutoff_per_t is None else cutoff_per_t / (T * 1e-3)
        try:
            if mode == "comparison":
                (p,) = shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=tr["reference_sensitivity"],
                                    u_reference_rel=U_REF, cutoff_hz=cutoff)
            else:
                (p,) = shock_pulses(c["laser"], c["out"], fs, laser=laser, cutoff_hz=cutoff)
        except Exception:  # noqa: BLE001 - a refused record quotes nothing: a miss
            out[T] = None
            continue
        warned = warn is not None and has_warning(p.warnings, warn)
        q = {"sensitivity": (p.sensitivity, p.u_sensitivity, true_peak_ratio(tr, fs), warned)}
        tf = p.transfer_function
        for j in TF_INDEX:
            f = tf.frequency_hz[j]
            h = tr["sensitivity"] * complex(resonance_response(f, tr["resonance_hz"], tr["resonance_q"]))
            q[f"tf_magnitude[{j}]"] = (tf.magnitude[j], tf.u_magnitude[j], abs(h), False)
            ph = math.degrees(math.atan2(h.imag, h.real))
            q[f"tf_phase[{j}]"] = (tf.phase_deg[j], tf.u_phase_deg[j], ph, False)
        out[T] = q
    return out


def _run(case: str, n_seeds: int, seed0: int, note: str, sim_kw: dict | None = None, *, warn_at=(), warn=None,
         **kw) -> list[CoverageRow]:
    vals: dict[str, list] = {}
    offset = 1_000_000 * sorted(SCENARIOS).index(case)  # each case draws its own noise
    for s in range(seed0, seed0 + n_seeds):
        res = one_seed(s + offset, sim_kw or {}, warn=warn, **kw)
        for T, q in res.items():
            if q is None:
                for name in ("sensitivity", *(f"tf_{w}[{j}]" for j in TF_INDEX for w in ("magnitude", "phase"))):
                    vals.setdefault(f"{name}@{T:g}ms", []).append((np.nan, np.nan, np.nan, False))
                continue
            for name, v in q.items():
                vals.setdefault(f"{name}@{T:g}ms", []).append(v)
    rows = []
    for k, v in vals.items():
        e, u, t, w = (np.array(x) for x in zip(*v))
        expect = "warn" if k in warn_at else "cover"
        rows.append(coverage_row(JOB, case, k, e.astype(float), u.astype(float), t.astype(float),
                                 warned=w.astype(bool) if expect == "warn" else None, expect=expect, note=note))
    return rows


def run_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Comparison, white noise 60 dB on both channels, reference u 0.05 % (drawn): must cover."""
    return _run("white", n_seeds, seed0, "60 dB, reference u 0.05 %")


def run_noise(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Comparison, 3x the noise, AR(1) 0.8 on both channels: must cover."""
    return _run("noise", n_seeds, seed0, "noise 3e-3, AR(1) 0.8",
                {"reference_noise_rel": 3e-3, "output_noise_rel": 3e-3, "noise_ar1": 0.8})


def run_filter(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Comparison with the stated low-pass at 5 / T on both channels: must cover."""
    return _run("filter", n_seeds, seed0, "low-pass 5/T, order 4", cutoff_per_t=5.0)


def run_zero_shift(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Zero shift of 1 % of the peak across the pulse: the peak ratios warn (zero-shift: corrected on a model
    whose doubt, half the shift rectangular, dominates their u), the transfer function covers."""
    return _run("zero-shift", n_seeds, seed0, "zero shift 1 %", {"zero_shift_rel": 0.01},
                warn_at=tuple(f"sensitivity@{T:g}ms" for T, _, _ in PULSES), warn="zero-shift")


def run_ringing(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Resonance 30 kHz, Q 30: the 0.05 and 1 ms peak ratios warn (shock-ringing), the rest covers."""
    return _run("ringing", n_seeds, seed0, "resonance 30 kHz, Q 30", {"resonance_hz": 30e3},
                warn_at=("sensitivity@0.05ms", "sensitivity@1ms"), warn="shock-ringing")


def run_primary_velocity(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """ISO 16063-13, laser velocity (noise 1e-3 of the velocity change), low-pass 10 / T: must cover."""
    return _run("primary-velocity", n_seeds, seed0, "laser velocity, low-pass 10/T", mode="primary",
                laser="velocity", cutoff_per_t=10.0)


def run_primary_displacement(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """ISO 16063-13, laser displacement (1 nm noise), low-pass 10 / T: must cover."""
    return _run("primary-displacement", n_seeds, seed0, "laser displacement 1 nm, low-pass 10/T", mode="primary",
                laser="displacement", cutoff_per_t=10.0)


SCENARIOS = {"white": run_white, "noise": run_noise, "filter": run_filter, "zero-shift": run_zero_shift,
             "ringing": run_ringing, "primary-velocity": run_primary_velocity,
             "primary-displacement": run_primary_displacement}

for _f in SCENARIOS.values():
    _f.full_seeds = 200  # type: ignore[attr-defined]
    _f.ci_seeds = 6  # type: ignore[attr-defined]
