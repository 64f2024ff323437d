"""Demo: double-centrifuge frequency response and hydraulic velocity-sensor calibration."""

from __future__ import annotations

import math
from pathlib import Path

from dataclasses import replace
from datetime import date, timedelta

from senscal.demo import DemoSection
from senscal.jobs.vibration import ResponseOptions, VelocityOptions, response, velocity
from senscal.report.certificate import response_figure, write_certificate
from senscal.report.dcc import write_dcc
from senscal.report.lab import Standard, example_info
from senscal.report.plots import save_figure
from senscal.simulate.common import write_simulation
from senscal.simulate.vibration import simulate_centrifuge, simulate_hydraulic

ORDER = 10
# Type B inputs of the demo's certificates (relative standard uncertainties): S0 from a static calibration, and
# the position reference's scale as its own (simulated) certificate states it.
U_S0 = 0.001
U_POSITION = 0.0005
TITLE = "Vibration calibration (double centrifuge, hydraulic rig)"


def run(out: Path, seed: int) -> DemoSection:
    folder = out / "vibration"
    # Double centrifuge: a0 = 100 m/s^2, turntable at 0.1, 1, 5, 10 Hz; records cut to whole revolutions.
    recs, truth = simulate_centrifuge(seed=seed)
    paths = write_simulation(recs, truth, folder / "centrifuge", "centrifuge")
    s0 = truth["static_sensitivity"]
    (a0,) = {tp["acceleration"] for tp in truth["points"]}
    # phi_0 from a start-up run at 0.05 Hz (the paper's procedure); without it the phase delays would
    # rest on encoder zero lying along the field and carry the phase-reference-unknown warning
    srecs, _ = simulate_centrifuge(frequencies=(0.05,), min_duration=0.0, revolutions=2.2, seed=seed + 1)
    # the simulated recordings themselves (not their CSV copies), labelled with the file names the certificate lists
    resp = response([replace(r, source=p.name) for r, p in zip(recs, paths)],
                    ResponseOptions(output="output", angle="angle", input_amplitude=a0, static_sensitivity=s0,
                                    u_input=0.001, u_static_sensitivity=U_S0,
                                    phase_reference=replace(srecs[0], source="startup.csv"))).response
    # a fictitious lab and customer fill every ISO/IEC 17025 field; HTML, PDF and DCC carry the same id
    info = example_info(item="servo accelerometer", model="second-order model (fn 40 Hz, damping 0.6)",
                        serial="DEMO-ACC-001", certificate_id="SC-DEMO-ACC-001")
    cert = dict(info=info, unit=resp.unit, files=[p.name for p in paths],
                method=("Double centrifuge: three-parameter least-squares sine fit of the output against the "
                        "turntable angle over whole revolutions"),
                conditions={"peak input acceleration (m/s²)": 100.0, "input amplitude u (type B)": "0.1 %",
                            "static sensitivity S0": f"{s0:g} V/(m/s²), u {100 * U_S0:g} % (type B)",
                            "input phase φ0": resp.phase_reference})
    for suffix in (".html", ".pdf"):
        write_certificate(folder / f"centrifuge_certificate{suffix}", "response", resp, **cert)
    write_dcc(folder / "centrifuge_certificate.xml", "response", resp, info, unit=resp.unit, method=cert["method"],
              files=cert["files"])
    save_figure(response_figure(resp), folder / "centrifuge_bode.png")
    rows = []
    for p, tp in zip(resp.points, truth["points"]):
        # rows show the fit (type A) uncertainty so truth-vs-estimate is judged on the noise
        u_a = p.normalized_budget.component("output fit (type A)").standard_uncertainty
        rows += [
            {"quantity": f"S_i/S_0 at {tp['frequency_hz']:g} Hz", "truth": tp["normalized_sensitivity"],
             "estimate": p.normalized_sensitivity, "uncertainty": u_a, "unit": "1",
             "note": "u of the fit only (type A), to judge the estimate against the simulated truth; the "
                     "certificate's U adds the type B inputs (input amplitude, S0)"},
            {"quantity": f"phase delay at {tp['frequency_hz']:g} Hz", "truth": tp["phase_delay_deg"],
             "estimate": math.degrees(p.phase_delay), "uncertainty": math.degrees(p.u_phase_delay), "unit": "deg"},
        ]
    # Hydraulic rig: velocity sensor against the position reference at 10 frequencies.
    hrecs, htruth = simulate_hydraulic(seed=seed)
    hpaths = write_simulation(hrecs, htruth, folder / "hydraulic", "hydraulic")
    # the position reference's own u (its certificate) enters the budget: a calibration is never better than it
    pos_std = Standard("Position reference, linear encoder (simulated)", "SIM-002", "SIM-CERT-0002",
                       "none: simulated data", (date.today() + timedelta(days=365)).isoformat(), U_POSITION)
    cal = velocity([replace(r, source=p.name) for r, p in zip(hrecs, hpaths)],
                   VelocityOptions(position="position", velocity="velocity", u_position=U_POSITION)).calibration
    write_certificate(folder / "velocity_certificate.html", "velocity", cal, unit=cal.unit,
                      info=example_info(item="moving-coil velocity sensor", model="0.1368 V/(m/s) model",
                                        serial="DEMO-VEL-001", certificate_id="SC-DEMO-VEL-001",
                                        standards=(pos_std,)),
                      method=("Hydraulic rig: least-squares sine fits of the sensor output and the position "
                              "reference at a shared frequency"),
                      conditions={"frequency points": len(cal.points),
                                  "peak displacement (m)": htruth["position_amplitude_m"],
                                  "position reference u (type B)": f"{100 * U_POSITION:g} %"},
                      files=[p.name for p in hpaths])
    rows.append({"quantity": "velocity sensor mean sensitivity", "truth": htruth["sensitivity"],
                 "estimate": cal.sensitivity, "uncertainty": cal.u_sensitivity, "unit": cal.unit})
    rows.append({"quantity": "velocity sensor phase at 5.5 Hz", "truth": htruth["points"][-1]["phase_deg"],
                 "estimate": math.degrees(cal.points[-1].phase), "uncertainty": math.degrees(cal.points[-1].u_phase),
                 "unit": "deg"})
    return DemoSection(
        key="vibration", title=TITLE,
        summary=("Double centrifuge: 100 m/s^2 turned at 0.1, 1, 5 and 10 Hz, accelerometer a second-order system "
                 "(natural frequency 40 Hz, damping 0.6), records starting mid-revolution; each record is cut to whole "
                 "revolutions at a 360 deg crossing and fitted against the turntable angle. Hydraulic rig: velocity "
                 "sensor (0.1368 V/(m/s), 0.5 ms delay, drifting offset) against a position reference at 10 "
                 "frequencies. Both calibrations are written as certificates (a fictitious lab and customer fill the "
                 "ISO/IEC 17025 fields); the frequency response also as a PDF and a Digital Calibration Certificate "
                 "(PTB DCC XML, validated against its schema)."),
        rows=tuple(rows), plot="vibration/centrifuge_bode.png",
        files=("vibration/centrifuge_certificate.html", "vibration/centrifuge_certificate.pdf",
               "vibration/centrifuge_certificate.xml", "vibration/velocity_certificate.html",
               "vibration/centrifuge/centrifuge_truth.json", "vibration/hydraulic/hydraulic_truth.json"),
    )
