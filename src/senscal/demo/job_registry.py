"""Demo: a sensor registry with a drifting and a stable accelerometer; drift, significance, due date."""

from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path

from senscal.demo import DemoSection
from senscal.registry import Quantity, open_registry
from senscal.registry.plot import plot_history
from senscal.simulate.common import write_truth
from senscal.simulate.registry import simulate_calibration_history

ORDER = 60
TITLE = "Sensor registry: drift between calibrations and due date"

Q, UNIT, TOL = "sensitivity@160Hz", "V/(m/s^2)", 0.01


def run(out: Path, seed: int) -> DemoSection:
    folder = out / "registry"
    folder.mkdir(parents=True, exist_ok=True)
    db = folder / "registry.sqlite"
    for p in folder.glob("registry.sqlite*"):
        p.unlink()  # a fresh registry per demo run
    drifting, truth_d = simulate_calibration_history(n_records=7, value=0.0100, drift_per_year=1.2e-5, u_rel=4e-4,
                                                     seed=seed)
    stable, truth_s = simulate_calibration_history(n_records=7, value=0.0098, drift_per_year=0.0, u_rel=4e-4,
                                                   seed=seed + 1000)
    write_truth({"DRIFT-01": truth_d, "STABLE-02": truth_s}, folder / "history_truth.json")
    reports = {}
    with open_registry(db) as reg:
        for serial, recs in (("DRIFT-01", drifting), ("STABLE-02", stable)):
            reg.add_sensor(serial, "accelerometer", model="piezo IEPE", nominal={Q: {"value": recs[0]["value"],
                                                                                        "unit": UNIT}})
            for r in recs:
                reg.record(serial, [Quantity(Q, r["value"], r["uncertainty"], UNIT, 2.0)], performed_at=r["date"],
                           job="manual", method="back-to-back comparison (simulated)", operator="demo")
            reports[serial] = reg.drift(serial, Q, tolerance=TOL)
        points = reg.history("DRIFT-01", Q)
        (folder / "registry_export.json").write_text(json.dumps(reg.export(), indent=2) + "\n")
    rep = reports["DRIFT-01"]
    plot_history(points, folder / "history.png", report=rep, title="DRIFT-01: sensitivity history, drift and due date")
    first = rep.first_date
    years = lambda d: (d - first).total_seconds() / 86400.0 / 365.25  # noqa: E731
    # Truth of the due date: where the noiseless line leaves the ±1 % band around the reference
    # (the first recorded value, itself noisy), without any uncertainty added.
    ref = drifting[0]["value"]
    true_cross = (ref * (1 + TOL) - truth_d["value"]) / truth_d["drift_per_year"]
    rows = [
        {"quantity": "DRIFT-01 drift per year", "truth": truth_d["drift_per_year"], "estimate": rep.drift_per_year,
         "uncertainty": rep.u_drift_per_year, "unit": f"{UNIT}/yr"},
        {"quantity": "STABLE-02 drift per year", "truth": 0.0, "estimate": reports["STABLE-02"].drift_per_year,
         "uncertainty": reports["STABLE-02"].u_drift_per_year, "unit": f"{UNIT}/yr"},
        {"quantity": "DRIFT-01 due (years after first calibration)", "truth": true_cross,
         "estimate": years(rep.due_date) if rep.due_date else None, "uncertainty": None, "unit": "yr"},
    ]
    today = datetime.now(timezone.utc).date()

    def due_text(r) -> str:
        if not r.due_date:
            return "none within 100 yr"
        d = r.due_date.date()
        return f"{d.isoformat()} (overdue: {(today - d).days} days ago)" if d < today else d.isoformat()

    table = {"title": "Drift test and due dates (tolerance ±1 % of the first record, bound = |deviation| + 2u)",
             "columns": ["sensor", "drift %/yr", "U (k=2) %/yr", "p-value", "significant", "due date"],
             "rows": [[s, 100 * r.relative_drift_per_year, 200 * r.u_relative_drift_per_year, r.fit.p_value,
                       "yes" if r.significant else "no", due_text(r)]
                      for s, r in reports.items()]}
    # the word follows the sign of the simulated drift (the estimate and the plot show the same direction)
    trend = "gains" if truth_d["drift_per_year"] > 0 else "loses"
    return DemoSection(
        key="registry", title=TITLE,
        summary=(f"Two accelerometers, seven yearly certificates each (dates jittered by up to 30 days, standard "
                 f"uncertainty 0.03-0.06 %): DRIFT-01 {trend} sensitivity at {abs(truth_d['drift_per_year']):.2g} "
                 f"{UNIT} per year ({100 * abs(truth_d['drift_per_year']) / truth_d['value']:.2g} %/yr), STABLE-02 "
                 "does not drift. Both are stored in a SQLite registry, "
                 "the drift is a weighted straight line through each history, and the due date is when the "
                 "predicted deviation plus twice its uncertainty reaches ±1 %. The due date comes before the "
                 "noiseless crossing (the 'truth' row) by design: it includes the uncertainty of the prediction."),
        rows=tuple(rows), plot="registry/history.png", tables=(table,),
        files=("registry/registry_export.json", "registry/history_truth.json"),
    )
