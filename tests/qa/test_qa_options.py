"""QA: non-finite option values and unreadable side files are one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.cli.common import parse_floats, parse_relative
from senscal.errors import InputError


def _one_line_error(r):
    assert r.code == 2, (r.code, r.err)
    assert "Traceback" not in r.err
    assert len(r.err.strip().splitlines()) == 1, r.err


@pytest.mark.parametrize("text", ["nan", "1,inf", "-inf,2"])
def test_parse_floats_refuses_non_finite(text):
    with pytest.raises(InputError, match="finite"):
        parse_floats(text, "--x")


@pytest.mark.parametrize("text", ["nan", "inf", "inf%", "nan%"])
def test_parse_relative_refuses_non_finite(text):
    with pytest.raises(InputError, match="finite"):
        parse_relative(text, "--u-x")


def test_parse_helpers_keep_good_values():
    assert parse_floats("1, 2.5,3", "--x") == [1.0, 2.5, 3.0]
    assert parse_relative("0.2%", "--u") == pytest.approx(0.002)


def test_gfimu_nan_initial_omega(cli, tmp_path):
    r = cli("simulate", "gfimu", "--out", tmp_path, "--seed", "0")
    assert r.code == 0, r.err
    _one_line_error(cli("gfimu", tmp_path / "gfimu.csv", "--initial-omega", "nan,0,0"))


def test_drift_model_that_is_a_folder(cli, tmp_path):
    from senscal.io import Recording, write_recording

    t = np.arange(50.0)
    write_recording(Recording({"a": np.ones(50), "b": np.ones(50)}, t=t), tmp_path / "d.csv")
    _one_line_error(cli("drift", tmp_path / "d.csv", "--preset", "model", "--model", tmp_path))


@pytest.mark.parametrize("opts", [["--preset", "redundant", "--channels", "a,b", "--trusted", "a",
                                   "--signal", "gauss_markov", "--signal-tau", "100", "--signal-mean", "nan"],
                                  ["--preset", "covariate", "--channels", "a", "--covariate", "b",
                                   "--covariate-reference", "inf"]])
def test_drift_non_finite_model_numbers(cli, tmp_path, opts):
    from senscal.io import Recording, write_recording

    rng = np.random.default_rng(1)
    t = np.arange(200.0)
    write_recording(Recording({"a": rng.standard_normal(200), "b": rng.standard_normal(200)}, t=t), tmp_path / "d.csv")
    r = cli("drift", tmp_path / "d.csv", *opts)
    _one_line_error(r)
    assert "finite" in r.err


def test_gfimu_absurd_noise_std(cli, tmp_path):
    # 1e300 ran to exit 0 with NaN uncertainties (variances overflowed).
    r = cli("simulate", "gfimu", "--out", tmp_path, "--seed", "0", "--duration", "1")
    assert r.code == 0, r.err
    _one_line_error(cli("gfimu", tmp_path / "gfimu.csv", "--method", "kalman", "--noise-std", "1e300"))
