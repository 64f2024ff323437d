"""QA: triaxial calibrate option values that used to crash."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def mag(tmp_path_factory):
    from senscal.io import write_recording
    from senscal.simulate.triaxial import simulate_magnetometer

    rec, _ = simulate_magnetometer(motion="sphere", seed=1)
    return write_recording(rec, tmp_path_factory.mktemp("mag") / "m.csv")


@pytest.mark.parametrize("opts", [["--static", "--static-window", "nan"], ["--static", "--min-pose", "nan"],
                                  ["--outlier-sigma", "nan"], ["--outlier-sigma", "-3"],
                                  ["--field", "1e300"], ["--field", "1e-300"]])
def test_bad_numbers_are_one_line_errors(cli, mag, opts):
    r = cli("triaxial", "calibrate", mag, "--channels", "x,y,z", *opts)
    assert r.code == 2, (r.code, r.err)
    assert "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1, r.err


def test_field_in_another_unit_still_calibrates(cli, mag):
    # 50 uT for data in nT: the gains absorb the factor 1000; that is a legitimate use.
    r = cli("triaxial", "calibrate", mag, "--channels", "x,y,z", "--field", "50", "--json")
    assert r.code == 0, r.err
