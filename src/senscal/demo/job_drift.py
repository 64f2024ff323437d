"""Demo: slow-drift correction of redundant sensors (augmented Kalman filter)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from senscal.demo import DemoSection
from senscal.drift.plot import plot_drift
from senscal.io import Recording, write_recording
from senscal.jobs.drift import DriftOptions, drift
from senscal.simulate.common import write_truth
from senscal.simulate.drift import simulate_drift

ORDER = 40
TITLE = "Slow-drift bias correction (Kalman)"


def run(out: Path, seed: int) -> DemoSection:
    folder = out / "drift"
    rec, truth = simulate_drift(days=8.0, dt=600.0, seed=seed)
    write_recording(rec, folder / "drift.csv")
    write_truth(truth, folder / "drift_truth.json")
    # The alternative-model fits (compare) would double the demo's run time;
    # the innovation checks still run and their verdict is shown.
    job = drift(rec, DriftOptions(preset="redundant", channels=("ref", "drift", "thermal"), trusted=("ref",),
                                  covariate="temperature", compare=False))
    res = job.result
    t, cols, units = job.columns()
    write_recording(Recording(cols, t=t, units=units), folder / "drift_corrected.csv")
    plot_drift(res, {c: rec[c] for c in res.channels}, folder / "drift.png", truth_signal=truth["signal"],
               truth_bias={"drift": truth["bias_drift"], "thermal": truth["bias_thermal"]}, unit="kPa")

    i = res.channels.index("drift")
    rms = float(np.sqrt(np.mean((res.corrected[i] - truth["signal"]) ** 2)))
    alpha, u_alpha = res.final("thermal_temperature_coefficient")
    noise = {p.name: p for p in res.noise}
    rows = [
        {"quantity": "drift: final bias", "truth": truth["bias_drift"][-1], "estimate": float(res.bias[i, -1]),
         "uncertainty": float(res.bias_std[i, -1]), "unit": "kPa"},
        {"quantity": "drift: onset of the ramp", "truth": truth["ramp_start_s"] / 3600,
         "estimate": None if res.onset_t["drift"] is None else res.onset_t["drift"] / 3600, "uncertainty": None,
         "unit": "h"},
        {"quantity": "drift: RMS of corrected - true quantity", "truth": truth["noise_std"], "estimate": rms,
         "uncertainty": None, "unit": "kPa"},
        {"quantity": "thermal: temperature coefficient", "truth": truth["temperature_coefficient"],
         "estimate": alpha, "uncertainty": u_alpha, "unit": "kPa/degC"},
    ]
    for c in ("ref", "drift", "thermal"):
        p = noise[f"{c}_noise_std"]
        rows.append({"quantity": f"{c}: noise std (ML)", "truth": truth["noise_std"], "estimate": p.value,
                     "uncertainty": p.std, "unit": "kPa"})
    return DemoSection(
        key="drift", title=TITLE,
        summary=("Three sensors of a slowly varying pressure over 8 days (10-min samples): 'ref' is trusted, "
                 f"'drift' starts a {truth['ramp_rate_per_s'] * 86400:g} kPa/day ramp on day "
                 f"{truth['ramp_start_s'] / 86400:g}, 'thermal' has a bias of "
                 f"{truth['temperature_coefficient']} kPa/degC times the daily temperature swing. The augmented "
                 "Kalman filter (redundant preset with the temperature covariate) estimates the biases on line, "
                 "with noise levels by maximum likelihood and a CUSUM drift-onset detector. Innovation check: "
                 + ("white, model adequate" if res.check.adequate else "model rejected")
                 + (f"; warnings: {'; '.join(res.warnings)}" if res.warnings else "; no warning") + "."),
        rows=tuple(rows), plot="drift/drift.png",
        files=("drift/drift.csv", "drift/drift_truth.json", "drift/drift_corrected.csv"),
    )
