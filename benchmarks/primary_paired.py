"""Paired before/after check of ``senscal primary``'s and the sine fit's results (issue 28, the speed work).

    PYTHONPATH=<old src> python3 benchmarks/primary_paired.py capture before.json [--seeds 5] [--only hum,...]
    PYTHONPATH=<new src> python3 benchmarks/primary_paired.py capture after.json  [--seeds 5]
    python3 benchmarks/primary_paired.py compare before.json after.json

``capture`` calibrates simulated interferometer points (the same seeds each time) in several settings -- the
issue's 1 MS/s record (shortened to 0.25 s so that a run takes minutes), a 200 kS/s record below the compiled
kernels' threshold, mains hum (the tone search and refit), a laser intensity drift (the ellipse refit), exciter
distortion with output drift, coloured displacement noise (the coloured-noise covariance), and the heterodyne
carrier -- and fits sines directly with the engine the vibration, shaft and response jobs share (harmonics,
drift, coloured noise, sample-clock jitter, a batch of channels, an estimated frequency).  It stores the
sensitivity, phase and every budget component's u (primary), and amplitude, phase, offset and their u, the
noise model and the warning names (sine fit).

``compare`` prints, per setting, the largest change of the sensitivity and of the phase in units of the
*before* u (``|after - before| / u``), the largest relative change of u, and how many results changed their
warnings or noise model.  A speed change that keeps the arithmetic shows values at rounding level (1e-9 and
below); snapshot the old source tree (``cp -r src /tmp/before_src``) before editing.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np

PRIMARY = {
    "1MSs-1kHz": dict(freq=1000.0, fs=1_000_000.0, duration=0.25),
    "200kSs-160Hz": dict(freq=160.0, fs=200_000.0, duration=0.5),
    "hum": dict(freq=315.0, fs=500_000.0, duration=0.4, hum_rel=3e-3),
    "intensity": dict(freq=800.0, fs=500_000.0, duration=0.4, intensity_drift=0.2),
    "distortion-drift": dict(freq=80.0, fs=200_000.0, duration=0.5, harmonic_distortion=0.01,
                             output_drift_rel=0.01),
    "coloured": dict(freq=500.0, fs=500_000.0, duration=0.4, displacement_noise_m=2e-10,
                     displacement_noise_ar1=0.9),
    "heterodyne": dict(freq=1000.0, fs=1_000_000.0, duration=0.25, heterodyne=True, carrier_hz=250_000.0),
}


def _names(ws) -> list[str]:
    return sorted(w.split(":")[0] for w in ws)


def _primary(name: str, kw: dict, seed: int) -> dict:
    from senscal.primary import calibrate_point
    from senscal.primary.heterodyne import calibrate_heterodyne
    from senscal.simulate.interferometer import simulate_interferometer

    rec, _ = simulate_interferometer(seed=seed, **kw)
    c, fs, f = rec.channels, kw["fs"], kw["freq"]
    if kw.get("heterodyne"):
        p, _ = calibrate_heterodyne(c["H"], c["out"], fs, carrier_hz=kw["carrier_hz"], reference=c["ref"], freq=f)
    else:
        p = calibrate_point(c["I"], c["Q"], c["out"], fs, freq=f)
    comp = {k: [v["u_rel"], v["u_phase_deg"]] for k, v in p.budget.items()}
    return dict(kind="primary", scen=name, value=[p.sensitivity, p.phase_deg], u=[p.u_sensitivity, p.u_phase_deg],
                comp=comp, warnings=_names(p.warnings))


def _sine_cases(seed: int):
    """(name, y, fit_sine keywords) of the shared engine's settings."""
    rng = np.random.default_rng(1000 + seed)
    fs = 50_000.0
    out = []
    for n, tag in ((20_000, "small"), (400_000, "compiled")):
        t = np.arange(n) / fs
        f = 137.0 + rng.uniform(-1, 1)
        s = np.sin(2 * math.pi * f * t + 0.3)
        h = 0.02 * np.sin(2 * math.pi * 2 * f * t - 1.0) + 0.01 * np.sin(2 * math.pi * 3 * f * t + 2.0)
        white = rng.normal(0, 0.01, n)
        out.append((f"white-{tag}", 1.5 * s + 0.2 + white, dict(fs=fs, freq=f)))
        out.append((f"harm-drift-{tag}", 1.5 * s + h + 0.2 + 0.3 * t + white,
                    dict(fs=fs, freq=f, harmonics=3, drift=True)))
        e = np.zeros(n)
        z = rng.normal(0, 0.01, n)
        e[0] = z[0]
        for i in range(1, n):
            e[i] = 0.8 * e[i - 1] + z[i]
        out.append((f"coloured-{tag}", 1.5 * s + 0.2 + e, dict(fs=fs, freq=f, harmonics=2)))
        jit = np.sin(2 * math.pi * f * (t + rng.normal(0, 2e-5, n)) + 0.3)
        out.append((f"jitter-{tag}", jit + rng.normal(0, 1e-3, n), dict(fs=fs, freq=f)))
        batch = np.stack([a * s + rng.normal(0, 0.01, n) for a in (0.5, 1.0, 2.0)])
        out.append((f"batch-{tag}", batch, dict(fs=fs, freq=f, harmonics=2, drift=True)))
        out.append((f"estimated-{tag}", 1.5 * s + 0.2 + white, dict(fs=fs)))
    return out


def capture(out_path: str, seeds: int, only: list[str] | None = None) -> None:
    from senscal.sinefit import fit_sine

    out = []
    for name, kw in PRIMARY.items():
        if only and name not in only:
            continue
        t0 = time.process_time()
        for seed in range(seeds):
            out.append(_primary(name, kw, seed))
        print(f"{name}: {time.process_time() - t0:.1f} s CPU", flush=True)
    t0 = time.process_time()
    for seed in range(seeds):
        for name, y, kw in _sine_cases(seed):
            r = fit_sine(y, **kw)
            out.append(dict(kind="sine", scen=name, value=np.ravel([r.amplitude, r.phase, r.offset]).tolist(),
                            u=np.ravel([r.u_amplitude, r.u_phase, r.u_offset]).tolist(),
                            model=np.ravel(np.asarray(r.noise_model, dtype=object)).tolist(),
                            warnings=_names(r.warnings)))
    print(f"sine fits: {time.process_time() - t0:.1f} s CPU", flush=True)
    with open(out_path, "w") as fh:
        json.dump(out, fh)


def compare(a_path: str, b_path: str) -> None:
    from _paired import load_pairs

    by = load_pairs(a_path, b_path, "settings")
    print("| setting | n | max abs(change)/u | max abs(change of u)/u | warnings or model changed |")
    print("|---|---|---|---|---|")
    worst = 0.0
    for s, pairs in by.items():
        dz, du, changed = 0.0, 0.0, 0
        for a, b in pairs:
            ua, ub = np.array(a["u"], float), np.array(b["u"], float)
            va, vb = np.array(a["value"], float), np.array(b["value"], float)
            ok = ua > 0
            # phases (primary's phase_deg, the sine fit's phase) compared modulo a turn
            d = np.abs(vb - va)
            d = np.minimum(d, np.abs(d - 360.0)) if a["kind"] == "primary" else d
            dz = max(dz, float(np.max(d[ok] / ua[ok])) if ok.any() else 0.0)
            du = max(du, float(np.max(np.abs(ub[ok] - ua[ok]) / ua[ok])) if ok.any() else 0.0)
            if a["kind"] == "primary":
                for k, (ur, up) in a["comp"].items():
                    br, bp = b["comp"][k]
                    du = max(du, abs(br - ur) / ur if ur else abs(br), abs(bp - up) / up if up else abs(bp))
            changed += a["warnings"] != b["warnings"] or a.get("model") != b.get("model")
        worst = max(worst, dz)
        print(f"| {s} | {len(pairs)} | {dz:.2e} | {du:.2e} | {changed} |")
    print(f"\nlargest change of a value: {worst:.2e} u")


def main() -> None:
    from _paired import paired_main

    paired_main(__doc__, capture, compare, seeds=5, only_help="comma-separated primary settings (the sine fits always run)")


if __name__ == "__main__":
    main()
