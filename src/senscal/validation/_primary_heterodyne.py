"""Coverage scenarios of ``senscal primary --heterodyne`` (ISO 16063-41 style carrier, issue 28).

Every seed simulates four frequency points of a heterodyne interferometer (carrier at a quarter of the
sample rate) and the accelerometer: 10 Hz at 0.5 m/s^2 (250 kS/s, 0.5 s), 160 Hz (100 kS/s, 0.25 s),
1 kHz (250 kS/s, 0.1 s) and 5 kHz at 0.5 um (1 MS/s, 0.05 s; a 50 kHz Doppler shift on a 250 kHz carrier),
laser noise 2e-3 of the carrier amplitude and output noise 1e-3 (60 dB). Cases, all of which must cover:
``heterodyne-white`` (demodulated against the reference carrier channel); ``heterodyne-carrier`` (no
reference: the carrier 0.4 % off its nominal value and drifting 20 Hz over the record, fitted and removed);
``heterodyne-am`` (reference; 10 % amplitude modulation at 37 Hz and 2.5 times the laser noise).
Registered in :data:`senscal.validation.primary.SCENARIOS`.
"""

from __future__ import annotations

import numpy as np

from senscal.validation import CoverageRow, coverage_row

__all__ = ["HETERODYNE_SCENARIOS", "POINTS", "one_seed_heterodyne"]

JOB = "primary"
# frequency: (fs, duration, acceleration or None for the default)
POINTS = {10.0: (250_000.0, 0.5, 0.5), 160.0: (100_000.0, 0.25, None), 1000.0: (250_000.0, 0.1, None),
          5000.0: (1_000_000.0, 0.05, None)}


def one_seed_heterodyne(seed: int, sim_kw: dict, *, reference: bool = True, freqs=tuple(POINTS)):
    """Per frequency: (sensitivity, u, truth), (phase_deg, u, truth), warnings; None for a refused point."""
    from senscal.primary.heterodyne import calibrate_heterodyne
    from senscal.simulate.interferometer import simulate_interferometer

    out = {}
    for i, f in enumerate(freqs):
        fs, dur, acc = POINTS[f]
        rec, tr = simulate_interferometer(freq=f, acceleration=acc, fs=fs, duration=dur, seed=seed * 16 + i,
                                          heterodyne=True, carrier_hz=fs / 4, reference=reference, **sim_kw)
        c = rec.channels
        try:
            p, _ = calibrate_heterodyne(c["H"], c["out"], fs, carrier_hz=fs / 4,
                                        reference=c["ref"] if reference else None, freq=f)
        except Exception:  # noqa: BLE001 - a refused point quotes nothing: a miss
            out[f] = None
            continue
        out[f] = ((p.sensitivity, p.u_sensitivity, tr["sensitivity"]), (p.phase_deg, p.u_phase_deg, tr["phase_deg"]),
                  p.warnings)
    return out


_CASES = {
    # case: (independent draws, simulator options, reference channel, note)
    "heterodyne-white": (10, {}, True, "reference carrier, 60 dB"),
    "heterodyne-carrier": (11, {"carrier_offset_hz": None, "carrier_drift_hz": 20.0}, False,
                           "no reference; carrier 0.4 % off and drifting 20 Hz"),
    "heterodyne-am": (12, {"am_depth": 0.10, "laser_noise": 5e-3}, True, "AM 10 % at 37 Hz, laser noise 5e-3"),
}


def _run(case: str, n_seeds: int, seed0: int) -> list[CoverageRow]:
    tag_seed, kw, ref, note = _CASES[case]
    vals: dict[str, list] = {}
    for s in range(seed0, seed0 + n_seeds):
        res = {}
        for f in POINTS:
            k = dict(kw)
            if "carrier_offset_hz" in k:
                k["carrier_offset_hz"] = 0.004 * POINTS[f][0] / 4
            res.update(one_seed_heterodyne(s + 1_000_000 * tag_seed, k, reference=ref, freqs=(f,)))
        for f, r in res.items():
            tag = f"{f:g}Hz"
            nan3 = (np.nan, np.nan, np.nan)
            vals.setdefault(f"sensitivity@{tag}", []).append(nan3 if r is None else r[0])
            vals.setdefault(f"phase@{tag}", []).append(nan3 if r is None else r[1])
    rows = []
    for k, v in vals.items():
        e, u, t = (np.array(x, float) for x in zip(*v))
        rows.append(coverage_row(JOB, case, k, e, u, t, note=note))
    return rows


def _scenario(case: str):
    def run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
        return _run(case, n_seeds, seed0)

    run.__name__ = "run_" + case.replace("-", "_")
    run.__doc__ = f"{case}: {_CASES[case][3]}; must cover."
    run.full_seeds = 200  # type: ignore[attr-defined]
    run.ci_seeds = 5  # type: ignore[attr-defined]
    return run


HETERODYNE_SCENARIOS = {case: _scenario(case) for case in _CASES}
