"""Demo: gravity identification and compensation on a tilted rotating shaft."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from senscal.demo import DemoSection
from senscal.io import write_recording
from senscal.jobs.shaft import ShaftCalibrateOptions, ShaftCompensateOptions, shaft_calibrate, shaft_compensate
from senscal.shaft.plotting import plot_compensation
from senscal.simulate.common import write_truth
from senscal.simulate.shaft import simulate_shaft

ORDER = 20
TITLE = "Rotating shaft: gravity compensation, angular acceleration from one accelerometer"


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def run(out: Path, seed: int) -> DemoSection:
    folder = out / "shaft"
    cal, test, truth = simulate_shaft(seed=seed)
    alpha_true = truth.pop("_test_angular_acceleration")
    write_recording(cal, folder / "shaft_cal.csv", units_in_header=True)
    write_recording(test, folder / "shaft_test.csv", units_in_header=True)
    write_truth(truth, folder / "shaft_truth.json")
    # The jobs read the files as a user's command would: the angle unit (deg) comes from the CSV header.
    model = shaft_calibrate(folder / "shaft_cal.csv", ShaftCalibrateOptions(angle="angle", accel="accel")).model
    model.save(folder / "model.json")
    r = truth["radius"]
    compensated = shaft_compensate(folder / "shaft_test.csv",
                                   ShaftCompensateOptions(model=model, radius=r, centripetal=True))
    res = compensated.compensation
    write_recording(compensated.output_recording(), folder / "compensated.csv")
    plot_compensation(folder / "compensation.png", model, res.angle, np.asarray(test["accel"]),
                      res.tangential_acceleration, unit=truth["output_unit"],
                      title=f"test run, r = {r} m: before/after gravity compensation", t=res.t,
                      alphas={"compensated, smoothed": res.angular_acceleration_smoothed,
                              "encoder (Savitzky-Golay)": res.angular_acceleration_encoder,
                              "truth": alpha_true})
    g = truth["gravity"]
    floor = truth["angular_acceleration_noise_floor"]
    rows = [
        {"quantity": "gravity amplitude", "truth": g["amplitude"], "estimate": model.amplitude,
         "uncertainty": model.u_amplitude, "unit": "m/s^2"},
        {"quantity": "gravity phase", "truth": g["phase_deg"], "estimate": math.degrees(model.phase),
         "uncertainty": math.degrees(model.u_phase), "unit": "deg"},
        {"quantity": "offset (bias + centripetal leakage at calibration speed)", "truth": g["offset"],
         "estimate": model.offset, "uncertainty": model.u_offset, "unit": "m/s^2"},
        {"quantity": "shaft tilt from horizontal", "truth": truth["tilt_deg"], "estimate": math.degrees(model.tilt),
         "uncertainty": math.degrees(model.u_tilt), "unit": "deg"},
        {"quantity": "sensitive-axis misalignment", "truth": truth["misalignment_deg"],
         "estimate": math.degrees(res.misalignment), "uncertainty": math.degrees(res.u_misalignment), "unit": "deg"},
        {"quantity": "alpha RMS error, compensated (per sample)", "truth": floor,
         "estimate": _rms(res.angular_acceleration - alpha_true), "uncertainty": None, "unit": "rad/s^2"},
        {"quantity": "alpha RMS error, uncompensated", "truth": truth["uncompensated_error_amplitude"] / math.sqrt(2),
         "estimate": _rms(res.uncompensated_angular_acceleration - alpha_true), "uncertainty": None,
         "unit": "rad/s^2"},
        {"quantity": "alpha RMS difference accelerometer vs encoder (smoothed)", "truth": res.expected_rms_difference,
         "estimate": res.rms_difference, "uncertainty": None, "unit": "rad/s^2"},
    ]
    return DemoSection(
        key="shaft", title=TITLE,
        summary=(f"A tangential accelerometer at r = {r} m on a shaft tilted {truth['tilt_deg']} deg from horizontal "
                 f"(axis misaligned {truth['misalignment_deg']} deg, noise {truth['noise_std']} m/s^2, "
                 f"{truth['encoder_counts']}-count encoder). Calibration: 1 rev/s with "
                 f"{100 * truth['calibration']['ripple']:.0f}% speed ripple, gravity fitted against the encoder "
                 "angle with the ripple's angular acceleration regressed out. Test: 2 rev/s with a 50% speed "
                 "modulation; gravity and centripetal leakage removed, angular acceleration compared with the "
                 "encoder's Savitzky-Golay second derivative. For the error rows, 'truth' is what theory expects: "
                 "the noise floor noise/r, and g cos(tilt)/(r sqrt 2) without compensation."),
        rows=tuple(rows), plot="shaft/compensation.png",
        files=("shaft/shaft_cal.csv", "shaft/shaft_test.csv", "shaft/shaft_truth.json", "shaft/model.json",
               "shaft/compensated.csv"),
    )
