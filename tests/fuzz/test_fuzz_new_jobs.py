"""``imu calibrate``, ``imu apply``, ``primary`` and ``shock`` on structurally mutated recordings (hypothesis).

A valid simulated recording (units in its header) is edited one to three times: a column's unit
replaced (another dimension, an unknown or hostile unit, an empty bracket), a column renamed,
duplicated or dropped, a run of cells set to NaN, inf, 1e308, a subnormal, an empty field or text, a
column scaled to beyond the float range or to zero, the time column given in ms, hours or volts,
reversed or frozen, the rows cut to none, one or a few.  Whatever the edit, the command ends in a
result (exit 0), a named warning (3 with ``--strict``) or one ``senscal: ...`` line (exit 2): never a
traceback, never the safety net's internal error, never a hang, and the input file is never modified
(its SHA-256 before and after, :func:`_fuzz_harness.run_case`).  CI draws a few examples per command;
``SENSCAL_FUZZ=long`` many more.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from _fuzz_harness import CASE_TIMEOUT_S, LONG, TALLY, run_case
from senscal.io import write_recording

EXAMPLES = 120 if LONG else 10
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])

UNITS = ["m/s^2", "g", "mg", "rad/s", "deg/s", "deg/h", "mV", "V", "uV", "pC", "m", "um", "m/s", "mm/s", "degC",
         "degF", "K", "counts", "LSB", "%", "T", "Hz", "s", "ms", "raw", "", " ", "m/s^999999", "1/0", "[/bold]",
         "\u202e", "nan", "V^-17", "(", "°/s", "dps"]
CELLS = ["nan", "", "inf", "-inf", "1e308", "-1e308", "1e-320", "0", "-0", "abc", "1,5", "1e999", "NaN", "null"]


@st.composite
def edits(draw, n_cols: int):
    """One to three edits as (kind, arguments); applied by :func:`_apply` to a frame of ``n_cols`` columns."""
    out = []
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["unit", "unit", "rename", "drop", "cells", "cells", "scale", "time", "rows"]))
        col = draw(st.integers(0, n_cols - 1))
        if kind == "unit":
            out.append((kind, col, draw(st.sampled_from(UNITS))))
        elif kind == "rename":
            out.append((kind, col, draw(st.sampled_from(["", "dup", "t", "time", "x y", "ax", "I", "out", "ref",
                                                         "[mV]", "a,b"]))))
        elif kind == "drop":
            out.append((kind, col))
        elif kind == "cells":
            out.append((kind, col, draw(st.floats(0, 1)), draw(st.sampled_from([1, 3, 50, 10 ** 6])),
                        draw(st.sampled_from(CELLS))))
        elif kind == "scale":
            out.append((kind, col, draw(st.sampled_from([0.0, 1e-300, 1e300, -1.0, 1e6]))))
        elif kind == "time":
            out.append((kind, draw(st.sampled_from(["ms", "h", "V", "reverse", "freeze", "jitter"]))))
        else:
            out.append((kind, draw(st.sampled_from([0, 1, 2, 7, 0.5]))))
    return out


def _apply(frame: pd.DataFrame, ops) -> str:
    """The CSV text of ``frame`` after ``ops`` (the first column is the time, 't [s]')."""
    df = frame.astype(object).copy()
    cols = list(df.columns)
    for op in ops:
        kind = op[0]
        n = len(df)
        if kind in ("unit", "rename", "drop", "cells", "scale") and not cols:
            continue
        if kind == "unit":
            c = op[1] % len(cols)
            base = str(cols[c]).split(" [")[0]
            cols[c] = f"{base} [{op[2]}]"
        elif kind == "rename":
            c = op[1] % len(cols)
            cols[c] = cols[(c + 1) % len(cols)] if op[2] == "dup" else op[2]
        elif kind == "drop":
            c = op[1] % len(cols)
            df = df.drop(columns=df.columns[c])
            del cols[c]
        elif kind == "cells" and n:
            c = op[1] % len(cols)
            i = int(op[2] * (n - 1))
            df.iloc[i:i + op[3], c] = op[4]
        elif kind == "scale":
            c = op[1] % len(cols)
            with np.errstate(all="ignore"):
                df.iloc[:, c] = pd.to_numeric(df.iloc[:, c], errors="coerce").to_numpy(float) * op[2]
        elif kind == "time" and cols:
            t = pd.to_numeric(df.iloc[:, 0], errors="coerce").to_numpy(float)
            how = op[1]
            if how in ("ms", "h", "V"):
                cols[0] = f"t [{how}]"
                if how == "ms":
                    t = t * 1e3
            elif how == "reverse":
                t = t[::-1].copy()
            elif how == "freeze":
                t = np.full_like(t, t[0] if t.size else 0.0)
            else:
                step = abs(float(np.nanmedian(np.diff(t)))) if t.size > 1 else 0.0
                t = t + np.random.default_rng(0).normal(0, 0.3 * step if np.isfinite(step) else 0.0, t.size)
            df.iloc[:, 0] = t
        elif kind == "rows":
            k = op[1]
            df = df.iloc[: (int(k * n) if isinstance(k, float) else k)]
    df.columns = cols
    return df.to_csv(index=False, float_format="%.17g", na_rep="nan")


def _frame(rec) -> pd.DataFrame:
    return pd.DataFrame({"t [s]": rec.time, **{(f"{c} [{rec.units[c]}]" if rec.units.get(c) else c): rec[c]
                                               for c in rec.names}})


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    """Valid recordings (each command accepts its own: checked in test_seeds_run) and an IMU calibration."""
    from senscal.simulate.imu import simulate_imu
    from senscal.simulate.interferometer import simulate_interferometer
    from senscal.simulate.shock import simulate_shock

    d = tmp_path_factory.mktemp("fuzz_new_jobs")
    imu, _ = simulate_imu(seed=3, n_poses=13, fs=50.0, init_s=10.0)
    pri, _ = simulate_interferometer(freq=160.0, fs=20_000.0, duration=0.1, seed=8)
    cmp_, _ = simulate_shock(duration_ms=1.0, seed=1)
    las, _ = simulate_shock(duration_ms=1.0, mode="primary", seed=1)
    cal = d / "cal.json"
    p = write_recording(imu, d / "imu.csv", units_in_header=True)
    from _fuzz_harness import quiet_main

    code, _, err = quiet_main(["imu", "calibrate", p, "--out", cal])
    assert code == 0, err
    return _Seeds({"imu calibrate": (_frame(imu), ["imu", "calibrate", "{f}", "--json"]),
            "imu apply": (_frame(imu), ["imu", "apply", "{f}", "--params", str(cal), "--out", "{o}", "--json"]),
            "primary": (_frame(pri), ["primary", "{f}", "--json"]),
            "shock comparison": (_frame(cmp_), ["shock", "{f}", "--reference", "ref", "--reference-sensitivity",
                                                "1e-4 V/(m/s^2)", "--json"]),
            "shock laser": (_frame(las), ["shock", "{f}", "--laser", "laser", "--lowpass-hz", "10000", "--json"]),
            "_cal": cal})


class _Seeds(dict):
    def __repr__(self):  # hypothesis prints its arguments; the frames are not the story
        return "<seed recordings>"


def _run(cli, seeds, tmp_path, name, ops, strict=False):
    frame, argv = seeds[name]
    f = tmp_path / "in.csv"
    f.write_text(_apply(frame, ops), encoding="utf-8")
    out = tmp_path / "out.csv"
    out.unlink(missing_ok=True)
    args = [a.replace("{f}", str(f)).replace("{o}", str(out)) for a in argv] + (["--strict"] if strict else [])
    kind, detail = run_case(cli, args, [f, seeds["_cal"]], CASE_TIMEOUT_S)
    TALLY.add(f"new jobs: {name}", kind, detail)
    assert detail is None, f"{detail}\nedits: {ops!r}"
    return kind


@pytest.mark.parametrize("name", ["imu calibrate", "imu apply", "primary", "shock comparison", "shock laser"])
def test_seeds_run(cli, seeds, tmp_path, name):
    assert _run(cli, seeds, tmp_path, name, []) == "ok"


@SETTINGS
@given(ops=edits(7), strict=st.booleans())
def test_imu_calibrate_mutated(cli, seeds, tmp_path, ops, strict):
    _run(cli, seeds, tmp_path, "imu calibrate", ops, strict)


@SETTINGS
@given(ops=edits(7), strict=st.booleans())
def test_imu_apply_mutated(cli, seeds, tmp_path, ops, strict):
    _run(cli, seeds, tmp_path, "imu apply", ops, strict)


@SETTINGS
@given(ops=edits(4), strict=st.booleans())
def test_primary_mutated(cli, seeds, tmp_path, ops, strict):
    _run(cli, seeds, tmp_path, "primary", ops, strict)


@SETTINGS
@given(ops=edits(3), strict=st.booleans(), laser=st.booleans())
def test_shock_mutated(cli, seeds, tmp_path, ops, strict, laser):
    _run(cli, seeds, tmp_path, "shock laser" if laser else "shock comparison", ops, strict)


def test_imu_apply_never_writes_over_its_input(cli, seeds, tmp_path):
    """--out naming the input (directly or through a symlink) is refused before anything is written."""
    frame, _ = seeds["imu apply"]
    f = tmp_path / "in.csv"
    f.write_text(_apply(frame, []), encoding="utf-8")
    link = tmp_path / "link.csv"
    link.symlink_to(f)
    for out in (f, link):
        kind, detail = run_case(cli, ["imu", "apply", str(f), "--params", str(seeds["_cal"]), "--out", str(out)],
                                [f], CASE_TIMEOUT_S)
        assert kind == "clean" and detail is None, detail
    assert json.loads(seeds["_cal"].read_text())  # the calibration is untouched and still a document


@pytest.mark.parametrize("name, ops", [
    ("primary", [("scale", 0, 1e300)]),  # time x 1e300: the sine fit overflowed (internal error)
    ("imu calibrate", [("scale", 0, 1e300)]),
    ("shock comparison", [("scale", 0, 1e300)]),
    ("primary", [("scale", 1, 1e300)]),  # I x 1e300: the ellipse fit's matrix went singular
    ("imu calibrate", [("scale", 4, 1e300)]),  # gx x 1e300: the gyro residuals were not finite
    ("shock laser", [("scale", 1, 1e300)]),
])
def test_found_by_the_long_run(cli, seeds, tmp_path, name, ops):
    """What SENSCAL_FUZZ=long found (internal errors before the job refused them): one clean line now."""
    assert _run(cli, seeds, tmp_path, name, ops) == "clean"


# --- hostile option values (numbers and quantities) on the jobs and their simulators -----------------------------

HOSTILE = ["nan", "-inf", "inf", "1e308", "-1e308", "1e-320", "0", "-0", "-1", "abc", "", "1,5", "1e999",
           "5 V", "5 kHz", "5 ms", "5 %", "5 m/s^999999", "[/bold]"]

OPTIONS = {
    "imu calibrate": ["--gravity", "--static-window", "--min-pose", "--init-static"],
    "primary": ["--wavelength-nm", "--freq", "--harmonics", "--slices", "--u-gain-rel", "--u-gain-phase-deg",
                "--u-other-rel", "--u-wavelength-rel"],
    "shock comparison": ["--reference-sensitivity", "--u-reference", "--lowpass-hz", "--lowpass-order",
                         "--u-other"],
}
SIMULATORS = {
    "imu": (["--poses", "3", "--fs", "20", "--init", "2", "--pose", "1", "--rotation", "0.5"],
            ["--fs", "--init", "--pose", "--rotation", "--accel-noise", "--gyro-noise", "--gyro-ar1", "--bias-drift",
             "--temperature", "--g-sensitivity"]),
    "interferometer": (["--freqs", "160", "--fs", "20000", "--duration", "0.02"],
                       ["--freqs", "--fs", "--duration", "--sensitivity", "--phase-deg", "--acceleration",
                        "--laser-noise", "--harmonic-distortion", "--output-drift", "--hum"]),
    "shock": (["--durations-ms", "1"],
              ["--durations-ms", "--peak", "--fs", "--sensitivity", "--reference-sensitivity", "--u-reference",
               "--noise", "--noise-ar1", "--laser-noise", "--resonance-hz", "--resonance-q", "--zero-shift"]),
}


@SETTINGS
@given(data=st.data())
def test_job_options_hostile(cli, seeds, tmp_path, data):
    name = data.draw(st.sampled_from(sorted(OPTIONS)), label="job")
    frame, argv = seeds[name]
    f = tmp_path / "in.csv"
    if not f.exists():
        f.write_text(_apply(frame, []), encoding="utf-8")
    extra = []
    for opt in data.draw(st.lists(st.sampled_from(OPTIONS[name]), min_size=1, max_size=2, unique=True), label="opts"):
        extra.append(f"{opt}={data.draw(st.sampled_from(HOSTILE), label=opt)}")
    args = [a.replace("{f}", str(f)) for a in argv] + extra
    kind, detail = run_case(cli, args, [f, seeds["_cal"]], CASE_TIMEOUT_S)
    TALLY.add(f"new jobs options: {name}", kind, detail)
    assert detail is None, detail


@SETTINGS
@given(data=st.data())
def test_simulator_options_hostile(cli, tmp_path, data):
    name = data.draw(st.sampled_from(sorted(SIMULATORS)), label="simulator")
    base, opts = SIMULATORS[name]
    extra = [f"{o}={data.draw(st.sampled_from(HOSTILE), label=o)}"
             for o in data.draw(st.lists(st.sampled_from(opts), min_size=1, max_size=2, unique=True), label="opts")]
    kind, detail = run_case(cli, ["simulate", name, "--out", str(tmp_path / "sim"), "--seed", "1", *base, *extra], [],
                            CASE_TIMEOUT_S)
    TALLY.add(f"simulate {name} options", kind, detail)
    assert detail is None, detail
