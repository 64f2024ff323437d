"""Units carried through the jobs that need physical units (issue 32): an accelerometer array in g and a
truth in deg/s give the rates of m/s^2 and rad/s; a channel of another dimension is refused in one line."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.errors import InputError
from senscal.io import Recording, write_recording


@pytest.fixture(scope="module")
def arrays(tmp_path_factory):
    from senscal.gfimu import paper_layout, write_layout
    from senscal.simulate.gfimu import simulate_gfimu

    out = tmp_path_factory.mktemp("gfimu_units")
    rec, truth, _ = simulate_gfimu(fs=300.0, duration=1.5, seed=3, rest_s=0.3)
    write_layout(paper_layout(0.04), out / "layout.csv")
    write_recording(rec, out / "si.csv")
    g = Recording({n: rec[n] / 9.80665 for n in rec.names}, t=rec.time, units={n: "g" for n in rec.names})
    write_recording(g, out / "g.csv", units_in_header=True)
    volts = Recording(dict(rec.channels), t=rec.time, units={n: "V" for n in rec.names})
    write_recording(volts, out / "v.csv", units_in_header=True)
    write_recording(truth, out / "truth.csv")
    axes = [n for n in truth.names if n in ("wx", "wy", "wz")]
    deg = Recording({n: (np.degrees(truth[n]) if n in axes else truth[n]) for n in truth.names}, t=truth.time,
                    units={n: "deg/s" for n in axes})
    write_recording(deg, out / "truth_deg.csv", units_in_header=True)
    return out


def test_gfimu_converts_g_and_deg_per_s(arrays):
    from senscal.jobs.gfimu import GfimuOptions, gfimu

    opts = dict(layout=arrays / "layout.csv", method="all")
    si = gfimu(arrays / "si.csv", GfimuOptions(truth=arrays / "truth.csv", **opts))
    g = gfimu(arrays / "g.csv", GfimuOptions(truth=arrays / "truth_deg.csv", **opts))
    for m in si.estimate.omega:
        np.testing.assert_allclose(g.estimate.omega[m], si.estimate.omega[m], rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(g.truth_omega, si.truth_omega, rtol=1e-12)


def test_gfimu_refuses_volts(arrays):
    from senscal.jobs.gfimu import GfimuOptions, gfimu

    with pytest.raises(InputError, match=r"accelerometer channel .* is in 'V' \(a voltage\).*'m/s\^2'"):
        gfimu(arrays / "v.csv", GfimuOptions(layout=arrays / "layout.csv"))


def test_triaxial_calibrate_puts_three_axes_in_one_unit(tmp_path):
    """x in uT with y, z in nT: the axes are put in the first axis's unit (uT); V among them is refused."""
    from senscal.jobs.triaxial import TriaxialCalibrateOptions, triaxial_calibrate
    from senscal.simulate.triaxial import simulate_magnetometer

    rec, _ = simulate_magnetometer(motion="sphere", field=50000.0, seed=5)
    nt = Recording(dict(rec.channels), t=rec.time, units={c: "nT" for c in "xyz"})
    mixed = Recording({"x": rec["x"] / 1000.0, "y": rec["y"], "z": rec["z"]}, t=rec.time,
                      units={"x": "uT", "y": "nT", "z": "nT"})
    a = triaxial_calibrate(nt, TriaxialCalibrateOptions(field=50000.0))
    b = triaxial_calibrate(mixed, TriaxialCalibrateOptions(field=50.0))
    assert b.unit == "uT"
    np.testing.assert_allclose(np.asarray(b.calibration.calibration.offsets) * 1000.0,
                               a.calibration.calibration.offsets, rtol=1e-6, atol=1e-6)
    volts = Recording(dict(rec.channels), t=rec.time, units={"x": "nT", "y": "V", "z": "nT"})
    with pytest.raises(InputError, match=r"channel 'y' .* is in 'V' \(a voltage\)"):
        triaxial_calibrate(volts, TriaxialCalibrateOptions(field=50000.0))


def test_shaft_accelerometer_in_g_is_in_m_per_s2():
    """A tangential accelerometer channel in g: calibrate and compensate work in m/s^2 (sensitivity 1)."""
    from senscal.jobs.shaft import ShaftCalibrateOptions, ShaftCompensateOptions, shaft_calibrate, shaft_compensate
    from senscal.simulate.shaft import simulate_shaft

    cal, test, _ = simulate_shaft(seed=3, cal_duration=8.0, test_duration=4.0)

    def tagged(rec, unit, scale):
        return Recording({"angle": rec["angle"], "accel": rec["accel"] * scale}, t=rec.time,
                         units={"angle": "deg", "accel": unit})

    opts = ShaftCalibrateOptions(angle="angle", accel="accel")
    si = shaft_calibrate(tagged(cal, "m/s^2", 1.0), opts)
    g = shaft_calibrate(tagged(cal, "g", 1 / 9.80665), opts)
    assert g.model.output_unit == "m/s^2"
    assert g.model.amplitude == pytest.approx(si.model.amplitude, rel=1e-9)
    assert g.model.tilt == pytest.approx(si.model.tilt, rel=1e-9)
    comp = dict(angle="angle", accel="accel", model=si.model, radius=0.1)
    a = shaft_compensate(tagged(test, "m/s^2", 1.0), ShaftCompensateOptions(**comp))
    b = shaft_compensate(tagged(test, "g", 1 / 9.80665), ShaftCompensateOptions(**comp))
    np.testing.assert_allclose(b.accel, a.accel, rtol=1e-12)
    with pytest.raises(InputError, match=r"'V' \(a voltage\) but the sensor was calibrated in 'm/s\^2'"):
        shaft_compensate(tagged(test, "V", 1.0), ShaftCompensateOptions(**comp))
