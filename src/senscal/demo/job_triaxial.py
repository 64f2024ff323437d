"""Demo: three-axis magnetometer calibration (sphere coverage vs the seed's planar protocol)."""

from __future__ import annotations

import math
from pathlib import Path

from senscal.demo import DemoSection
from senscal.io import write_recording
from senscal.simulate.common import write_truth
from senscal.jobs.triaxial import TriaxialCalibrateOptions, triaxial_calibrate
from senscal.simulate.triaxial import simulate_magnetometer
from senscal.triaxial.plots import plot_calibration

ORDER = 50
TITLE = "Three-axis magnetometer calibration"


def run(out: Path, seed: int) -> DemoSection:
    folder = out / "triaxial"
    rec, truth = simulate_magnetometer(motion="sphere", n=500, seed=seed)
    write_recording(rec, folder / "magnetometer.csv")
    write_truth(truth, folder / "magnetometer_truth.json")
    h = rec.data(["x", "y", "z"])
    f = truth["field"]

    def calibrate(recording, **options):
        return triaxial_calibrate(recording, TriaxialCalibrateOptions(channels=("x", "y", "z"), **options)).calibration

    res = calibrate(rec, field=f)
    res.calibration.save(folder / "params.json")
    plot_calibration(h, res.calibration.apply(h), f, folder / "calibration.png", unit="nT",
                     title="Magnetometer: raw and corrected (full model, maximum likelihood)")
    rows = []
    for name, p in res.parameters.items():
        if name in ("alpha", "beta", "gamma"):
            rows.append({"quantity": name, "truth": truth[f"{name}_deg"], "estimate": math.degrees(p["value"]),
                         "uncertainty": math.degrees(p["u"]), "unit": "deg"})
        else:
            rows.append({"quantity": name, "truth": truth[name], "estimate": p["value"], "uncertainty": p["u"],
                         "unit": "1" if name.startswith("K") else "nT"})
    lin = calibrate(rec, field=f, method="linear")
    lms = calibrate(rec, field=f, method="lms")
    cmp_rows = []
    for n in ("alpha", "beta", "gamma"):
        cmp_rows.append([f"{n} (deg)", truth[f"{n}_deg"], math.degrees(res.value(n)), math.degrees(lin.value(n)),
                         math.degrees(lms.value(n))])
    for n, ln in (("Kx", "dKx"), ("Ky", "dKy")):
        cmp_rows.append([f"{n} - 1", truth[n] - 1, res.value(n) - 1, lin.value(ln), lms.value(ln)])
    for n in ("Bx", "By", "Bz"):
        cmp_rows.append([f"{n} (nT)", truth[n], res.value(n), lin.value(n), lms.value(n)])
    prec, ptruth = simulate_magnetometer(motion="planar", seed=seed)
    pres = calibrate(prec, field=f)
    write_recording(prec, folder / "planar_15.csv")
    b, a = res.norm_error_before, res.norm_error_after
    unid = "; ".join(g["reason"] for g in pres.unidentifiable)
    return DemoSection(
        key="triaxial", title=TITLE,
        summary=(f"A magnetometer with 0.8/-1.1/0.6 deg non-orthogonality, gains 1.03/0.98/1, offsets "
                 f"300/-200/150 nT and {truth['noise_std']:g} nT noise, turned through 500 orientations in a "
                 f"{f:g} nT field. The full model (ellipsoid start, maximum likelihood) brings the |H| error from "
                 f"{b['std']:.0f} nT std ({b['std_percent']:.2f} %) to {a['std']:.1f} nT ({a['std_percent']:.3f} %), "
                 f"the noise level. The seed's linearised model is compared below (least squares and LMS, lr 0.01, "
                 f"50 epochs; LMS ends {lms.lms_vs_least_squares['max_abs_difference_in_u']:.2g} u from least "
                 f"squares): its dropped second-order terms leave {lin.norm_error_after['std']:.1f} nT std. On the seed's own protocol (15 readings, one level turn) the tool falls back to the "
                 f"{pres.model} model and reports: {unid}."),
        rows=tuple(rows), plot="triaxial/calibration.png",
        files=("triaxial/magnetometer.csv", "triaxial/magnetometer_truth.json", "triaxial/params.json",
               "triaxial/planar_15.csv"),
        tables=({"title": "Full model vs the seed's linearised model",
                 "columns": ["quantity", "truth", "full ML", "linear LS", "LMS"], "rows": cmp_rows},),
    )
