"""One time-base rule for every command (issue 32 items 2-3, issue 26 items 8-9, issue 31 item 5).

The reading layer checks the time column for every job: a rate stated twice
(a preamble's ``Fs``, ``--fs``, the time column) must agree or the file is
refused with one line (exit 2); a time column that looks like ms or us read
as seconds is named ``time-unit-suspect`` (``--strict``: exit 3) on every
command, ``fit`` and ``allan`` included; irregular stamps give the mean rate
over the record; ``--start/--stop`` cut a window in seconds on every command
that reads a recording; a scope's ``Time(S)`` is time; a headerless x,y,z
file is not told ``--names t,x,y``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from senscal.errors import InputError
from senscal.io import Recording, read_recording
from senscal.io.plausibility import SLOW_LOGGER_JOBS, TIME_UNIT_WARNING, time_base_warnings
from senscal.io.recording import sample_rate_of

DATA = Path(__file__).resolve().parents[1] / "data"
SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"
GYRO = DATA / "imu_static_gyro_mpu6050_0p5s.csv"
MPU_FULL = SHARED / "imu_sunsided_static_10min_mpu6050.csv"
SCOPE = DATA / "sine_adalm2000_scope_1khz.csv"
QMC_FULL = SHARED / "mag_tomisuarez2_qmc5883l_filtered.csv"


def _sine(tmp_path: Path, name: str, *, scale: float = 1.0, header: str = "t", preamble: str = "",
          fs: float = 1000.0, n: int = 2000, f: float = 12.5) -> Path:
    """A 12.5 Hz sine at ``fs``; its time column multiplied by ``scale`` and headed ``header``."""
    t = np.arange(n) / fs
    y = np.sin(2 * np.pi * f * t + 0.3) + 0.01 * np.random.default_rng(0).standard_normal(n)
    path = tmp_path / name
    with open(path, "w", newline="") as fh:
        fh.write(preamble)
        pd.DataFrame({header: np.round(t * scale, 9), "y": y}).to_csv(fh, index=False)
    return path


def _one_line(r) -> bool:
    return r.code == 2 and len(r.err.strip().splitlines()) == 1 and "Traceback" not in r.err


def _suspect(r) -> list[str]:
    return [w for w in json.loads(r.out)["warnings"] if w.startswith(TIME_UNIT_WARNING)]


# --- the rule itself (pure) ------------------------------------------------------------------------------

def test_mean_rate_of_irregular_stamps_and_spacing_of_regular_ones():
    fs = 100.0
    regular = 1.7e9 + np.arange(1000) / fs
    assert math.isclose(sample_rate_of(regular), fs, rel_tol=1e-9)
    # A host reading a 100 Hz FIFO in bursts of 5: four 1-ms steps and one 46-ms step.
    steps = np.tile([0.001, 0.001, 0.001, 0.001, 0.046], 400)
    bursty = np.concatenate([[0.0], np.cumsum(steps)])
    assert 1.0 / np.median(np.diff(bursty)) == pytest.approx(1000.0)      # what the median said (10x)
    assert sample_rate_of(bursty) == pytest.approx(fs, rel=1e-12)          # the mean rate
    rec = Recording({"g": np.zeros(bursty.size)}, t=bursty)
    assert rec.sample_rate == pytest.approx(fs, rel=1e-12) and not rec.is_uniform


@pytest.mark.parametrize("job", ["fit", "allan", "gfimu", "shaft", "triaxial", "velocity", "response"])
def test_counter_clock_is_named_for_every_fast_job(job):
    ms = np.arange(2000, dtype=float)                                       # 1 kHz stamped in ms, read as s
    (w,) = time_base_warnings(ms, job)
    assert w.startswith(TIME_UNIT_WARNING) and "--time-unit ms" in w
    assert time_base_warnings(ms / 1000.0, job) == ()                       # the same in seconds
    assert time_base_warnings(ms, job, declared=True) == () or job in ("velocity", "response", "gfimu")


def test_whole_second_loggers_stay_quiet_for_drift():
    assert "drift" in SLOW_LOGGER_JOBS
    assert time_base_warnings(np.arange(0.0, 86400.0, 60.0), "drift") == ()


def test_seconds_labelled_ms_are_named_where_the_job_bounds_the_rate():
    t = np.arange(4000) / 1000.0 * 1e-3                                     # 1 kHz in s, converted from "ms"
    (w,) = time_base_warnings(t, "allan", unit="ms", declared=True)
    assert "seconds labelled ms" in w and "1e+06 Hz" in w
    assert time_base_warnings(np.arange(4000) / 1000.0, "allan", declared=True) == ()


# --- contradictions: refused with one line -----------------------------------------------------------------

def test_fs_against_the_preamble_and_the_time_column(cli, tmp_path):
    pre = _sine(tmp_path, "pre.csv", preamble="Fs,1000\n")
    r = cli("fit", pre, "--fs", "500", "--time-column", "none")
    assert _one_line(r) and "--fs 500 Hz contradicts" in r.err and "'Fs,1000'" in r.err, r.err
    assert cli("fit", pre, "--fs", "1000", "--time-column", "none").code == 0       # agreeing statements
    bad = _sine(tmp_path, "bad.csv", preamble="Fs,500\n")
    r = cli("fit", bad)
    assert _one_line(r) and "states 500 Hz" in r.err, r.err
    r = cli("allan", bad, "-c", "y")
    assert _one_line(r) and "states 500 Hz" in r.err, r.err
    # The preamble says 1000 Hz and a bare t counts milliseconds: refused, with the unit named.
    ms = _sine(tmp_path, "ms.csv", scale=1000.0, preamble="Fs,1000\n")
    r = cli("fit", ms)
    assert _one_line(r) and "--time-unit ms" in r.err, r.err
    r = cli("fit", ms, "--time-unit", "ms", "--json")
    assert r.code == 0 and json.loads(r.out)["channels"]["y"]["frequency_hz"] == pytest.approx(12.5, rel=1e-4)
    r = cli("fit", _sine(tmp_path, "plain.csv"), "--fs", "900")
    assert _one_line(r) and "contradicts the time column" in r.err, r.err


# --- suspicions: named on fit and allan as on the other commands --------------------------------------------

@pytest.mark.parametrize("scale,unit", [(1000.0, "ms"), (1e6, "us")])
def test_fit_on_milliseconds_or_microseconds_is_named(cli, tmp_path, scale, unit):
    path = _sine(tmp_path, f"{unit}.csv", scale=scale)
    r = cli("fit", path, "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["channels"]["y"]["frequency_hz"] == pytest.approx(12.5 / scale, rel=1e-3)   # the wrong answer ...
    assert len(_suspect(r)) == 1 and TIME_UNIT_WARNING in r.err                            # ... now named
    assert cli("fit", path, "--strict").code == 3
    r = cli("fit", path, "--time-unit", unit, "--json")
    assert r.code == 0 and _suspect(r) == []
    assert json.loads(r.out)["channels"]["y"]["frequency_hz"] == pytest.approx(12.5, rel=1e-4)
    assert _suspect(cli("fit", path, "--time-unit", "s", "--json")) == []                   # the user says seconds


def test_fit_known_frequency_on_seconds_labelled_ms(cli, tmp_path):
    path = _sine(tmp_path, "s_as_ms.csv", header="t [ms]")
    r = cli("fit", path, "--freq", "12.5", "--json")
    assert r.code == 0 and len(_suspect(r)) == 1 and "1000 times --freq" in _suspect(r)[0], r.err
    # With ms read as s, --freq 12.5 lies above the misread Nyquist frequency: the refusal says why.
    r = cli("fit", _sine(tmp_path, "ms.csv", scale=1000.0), "--freq", "12.5")
    assert _one_line(r) and TIME_UNIT_WARNING in r.err, r.err


def test_allan_on_milliseconds_and_on_seconds_labelled_ms(cli, tmp_path):
    ms = _sine(tmp_path, "ms.csv", scale=1000.0, n=4000)
    r = cli("allan", ms, "-c", "y", "--json")
    assert r.code == 0 and len(_suspect(r)) == 1, r.err
    assert cli("allan", ms, "-c", "y", "--strict").code == 3
    r = cli("allan", ms, "-c", "y", "--time-unit", "ms", "--json")
    assert r.code == 0 and _suspect(r) == [] and json.loads(r.out)["fs_hz"] == pytest.approx(1000.0)
    r = cli("allan", _sine(tmp_path, "s_as_ms.csv", header="t [ms]", n=4000), "-c", "y", "--json")
    assert r.code == 0 and len(_suspect(r)) == 1 and "seconds labelled ms" in _suspect(r)[0], r.err


# --- Allan on real host time stamps --------------------------------------------------------------------------

def _allantools_matches(doc: dict, y: np.ndarray) -> float:
    allantools = pytest.importorskip("allantools", reason="allantools (test extra) compares the Allan deviation")
    taus = np.array([r["tau_s"] for r in doc["rows"]])
    dev = np.array([r["dev"] for r in doc["rows"]])
    t2, ad, _, _ = allantools.oadev(y, rate=doc["fs_hz"], data_type="freq", taus=taus)
    assert np.array_equal(t2, taus)
    return float(np.max(np.abs(ad / dev - 1.0)))


def test_allan_uses_the_mean_rate_and_equals_allantools_on_the_excerpt(cli):
    r = cli("allan", GYRO, "-c", "gx", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    t = pd.read_csv(GYRO)["t"].to_numpy()
    assert doc["fs_hz"] == pytest.approx((t.size - 1) / (t[-1] - t[0]), rel=1e-12)
    assert _allantools_matches(doc, pd.read_csv(GYRO)["gx"].to_numpy()) < 1e-12


@pytest.mark.skipif(not MPU_FULL.exists(), reason=f"the shared real recording {MPU_FULL} is not beside the repository")
def test_allan_on_the_bursty_mpu6050_session(cli):
    r = cli("allan", MPU_FULL, "-c", "gx", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    # 65,067 samples in 655 s: 99.3 Hz, not the 491 Hz of the median interval inside a burst.
    assert doc["fs_hz"] == pytest.approx(99.317, abs=0.01)
    w = [x for x in doc["warnings"] if x.startswith("allan-irregular-sampling")]
    assert len(w) == 1 and "bursts" in w[0] and "mean rate" in w[0]
    assert _allantools_matches(doc, pd.read_csv(MPU_FULL)["gx"].to_numpy()) < 1e-12


# --- --start / --stop -----------------------------------------------------------------------------------------

def test_window_in_seconds_from_the_first_sample(tmp_path):
    path = _sine(tmp_path, "w.csv", n=2000)
    rec = read_recording(path, start=0.5, stop=1.0)
    assert rec.n_samples == 501 and rec.time[0] == pytest.approx(0.5) and rec.time[-1] == pytest.approx(1.0)
    # A file without time column (its preamble gives the rate) keeps its time base: t0 moves, the rate stays.
    pre = tmp_path / "pre.csv"
    pre.write_text("Fs,50.00\nInitialization time,60\nmx,my,mz\n" + "".join(f"{k},{-k},{2 * k}\n" for k in range(5000)))
    part, full = read_recording(pre, start=60.0), read_recording(pre)
    assert part.fs == full.fs == 50.0 and part.t0 == pytest.approx(60.0)
    assert part.n_samples == full.n_samples - 3000 and part["mx"][0] == 3000.0
    for start, stop, frag in ((-1.0, None, ">= 0"), (1.0, 0.5, "after --start"), (5.0, None, "holds 0 sample"),
                              (float("nan"), None, "finite")):
        with pytest.raises(InputError, match=frag):
            read_recording(path, start=start, stop=stop)


def test_every_command_that_reads_a_recording_takes_start_and_stop():
    import typer

    from senscal.cli import app
    from senscal.cli._manifest import build  # noqa: F401  (imports every command module)

    build()
    root = typer.main.get_command(app)

    def walk(cmd, path):
        subs = getattr(cmd, "commands", None)
        if subs:
            for name, sub in subs.items():
                yield from walk(sub, path + [name])
        else:
            yield " ".join(path), {o for p in cmd.params for o in getattr(p, "opts", [])}

    readers = {name: opts for name, opts in walk(root, []) if "--time-column" in opts}
    assert len(readers) >= 9, sorted(readers)
    missing = {name: sorted({"--start", "--stop", "--time-unit"} - opts) for name, opts in readers.items()
               if not {"--start", "--stop"} <= opts or ("--time-unit" not in opts and name != "triaxial apply")}
    assert not missing, missing


def test_start_stop_on_fit_allan_and_triaxial(cli, tmp_path):
    r = cli("fit", SCOPE, "-c", "CH1(V)", "--start", "0.002", "--stop", "0.004", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["channels"]["CH1(V)"]["n_samples"] == 2001
    full = json.loads(cli("allan", GYRO, "-c", "gx", "--json").out)
    part = json.loads(cli("allan", GYRO, "-c", "gx", "--start", "100", "--json").out)
    assert part["n_samples"] < full["n_samples"]
    if QMC_FULL.exists():
        # The QMC5883L session's documented 60 s static start, dropped (issue 26 item 9).
        r = cli("triaxial", "calibrate", QMC_FULL, "--channels", "mx,my,mz", "--start", "60", "--stop", "120",
                "--json")
        assert r.code == 0, r.err
        assert json.loads(r.out)["n_samples"] == read_recording(QMC_FULL, start=60.0, stop=120.0).n_samples == 3001
    # A file read on a sample-index time base has no seconds to cut.
    r = cli("triaxial", "calibrate", DATA / "magacc_ckexplorer_tumble_dec6.csv", "--channels", "mx,my,mz",
            "--start", "10")
    assert _one_line(r) and "--fs" in r.err, r.err
    r = cli("fit", SCOPE, "--start", "1")
    assert _one_line(r) and "--start/--stop" in r.err, r.err


# --- real files: the scope's Time(S), a headerless hint ----------------------------------------------------

def test_scope_time_column_is_time_in_seconds(cli):
    rec = read_recording(SCOPE)
    assert "Time(S)" not in rec.names and rec.t is not None
    assert rec.sample_rate == pytest.approx(1e6, rel=1e-9) and rec.time[0] == pytest.approx(-0.004)
    r = cli("fit", SCOPE, "-c", "CH1(V)", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["channels"]["CH1(V)"]["frequency_hz"] == pytest.approx(1000.0, rel=1e-4)


def test_headerless_hint_follows_the_columns(cli, tmp_path):
    xyz = tmp_path / "xyz.csv"
    xyz.write_text("0.10,0.20,-0.98\n0.12,0.18,-0.97\n0.09,0.21,-0.99\n0.11,0.19,-0.98\n")
    r = cli("triaxial", "calibrate", xyz, "--channels", "x,y,z")
    assert _one_line(r) and "--names x,y,z" in r.err and "t,x,y" not in r.err, r.err
    txyz = tmp_path / "txyz.csv"
    txyz.write_text("0.00,0.10,0.20,-0.98\n0.01,0.12,0.18,-0.97\n0.02,0.09,0.21,-0.99\n0.03,0.11,0.19,-0.98\n")
    r = cli("triaxial", "calibrate", txyz, "--channels", "x,y,z")
    assert _one_line(r) and "--names t,x,y,z" in r.err, r.err


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e308", "-1", "1e-320", "-0", "abc", ""])
def test_hostile_windows_are_one_line_or_a_result(cli, tmp_path, value):
    path = _sine(tmp_path, "h.csv")
    for opt in ("--start", "--stop"):
        r = cli("fit", path, f"{opt}={value}")
        assert r.code == 0 or _one_line(r), (opt, value, r.err)
