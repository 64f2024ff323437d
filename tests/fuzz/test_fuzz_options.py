"""Hostile option values (hypothesis): every command answers with a result or one clean error line.

Size-like options (sample rates, durations, counts) draw only from a list of
hostile values (never a mid-sized legal one, which would just be a long
simulation); other numeric options draw from all floats including NaN, inf,
subnormals and -0; text options from arbitrary text (markup-like included).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from _fuzz_harness import CASE_TIMEOUT_S, LONG, TALLY, run_case
from senscal.io import Recording, write_recording

HOSTILE = ["0", "-0", "-1", "nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "1e400", "abc", "", "9" * 30,
           "1e15", "-1e15", "0x10", "1_000", " 5", "[/]"]
hostile = st.sampled_from(HOSTILE)
any_float = st.one_of(hostile, st.floats(allow_nan=True, allow_infinity=True).map(repr))
text = st.one_of(st.sampled_from(["", " ", "[/]", "[bold]x[/bold]", "t", "x,x", "é", "$\\frac{$", "-", "--json"]),
                 st.text(alphabet=st.characters(blacklist_characters="\x00", blacklist_categories=("Cs",)),
                         max_size=12))


def opt(valid: str, bad=hostile):
    """Usually the valid value, so that cases reach past the first check to the others."""
    return st.one_of(st.just(valid), st.just(valid), bad)


EXAMPLES = 200 if LONG else 30
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture(scope="module")
def sine(tmp_path_factory):
    d = tmp_path_factory.mktemp("opt")
    t = np.arange(300) / 300.0
    return write_recording(Recording(channels={"x": np.sin(2 * np.pi * 7 * t) + 0.01 * np.cos(t * 99)}, t=t),
                           d / "s.csv")


def _check(cli, args, inputs, label):
    kind, detail = run_case(cli, [str(a) for a in args], inputs, CASE_TIMEOUT_S)
    TALLY.add(label, kind, detail)
    assert detail is None, detail


@SETTINGS
@given(freq=opt("7", any_float), harmonics=opt("1"), fs=opt("", hostile), column=opt("t", text),
       channel=opt("x", text))
def test_fit_options(cli, sine, freq, harmonics, fs, column, channel):
    args = ["fit", sine, "--freq", freq, "--harmonics", harmonics, "--time-column", column, "-c", channel]
    if fs:
        args += ["--fs", fs]
    _check(cli, args, [sine], "options: fit")


@SETTINGS
@given(seed=opt("1"), fs=opt("200"), duration=opt("0.5"), freq=opt("12.5", any_float), noise=opt("0.05", any_float),
       rho=opt("0", any_float))
def test_simulate_sine_options(cli, tmp_path_factory, seed, fs, duration, freq, noise, rho):
    out = tmp_path_factory.mktemp("sim")
    args = ["simulate", "sine", "--out", out, "--seed", seed, "--fs", fs, "--duration", duration, "--freq", freq,
            "--noise", noise, "--noise-rho", rho, "--channels", "1"]
    _check(cli, args, [], "options: simulate sine")


@SETTINGS
@given(field=opt("50", any_float), sigma=opt("5", any_float), window=opt("0.5", any_float))
def test_triaxial_options(cli, tmp_path_factory, field, sigma, window):
    d = tmp_path_factory.mktemp("tri")
    rng = np.random.default_rng(0)
    v = rng.normal(size=(120, 3))
    v = 50.0 * v / np.linalg.norm(v, axis=1)[:, None] + [3.0, -2.0, 1.0]
    f = write_recording(Recording(channels=dict(zip("xyz", v.T)), fs=10.0), d / "m.npz")
    args = ["triaxial", "calibrate", f, "--channels", "x,y,z", "--field", field, "--outlier-sigma", sigma,
            "--static-window", window]
    _check(cli, args, [f], "options: triaxial calibrate")
