"""QA: output paths never overwrite an input and give one-line errors."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from senscal.io import Recording, write_recording


def _sine(path, n=400, fs=100.0, f=5.0):
    t = np.arange(n) / fs
    rng = np.random.default_rng(0)
    rec = Recording({"position": np.sin(2 * np.pi * f * t) + 0.01 * rng.standard_normal(n),
                     "velocity": 0.3 * np.cos(2 * np.pi * f * t) + 0.01 * rng.standard_normal(n)}, t=t)
    write_recording(rec, path)
    return path


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _one_line_error(r):
    assert r.code == 2, r.err
    assert "Traceback" not in r.err
    assert len(r.err.strip().splitlines()) == 1, r.err


@pytest.mark.parametrize("opt", ["--report", "--plot"])
def test_velocity_never_overwrites_its_input(cli, tmp_path, opt):
    f = _sine(tmp_path / "v.csv")
    before = _digest(f)
    r = cli("velocity", f, "--position", "position", "--velocity", "velocity", opt, f)
    _one_line_error(r)
    assert _digest(f) == before


def test_output_under_a_file_and_folder_output_are_one_line_errors(cli, tmp_path):
    f = _sine(tmp_path / "v.csv")
    (tmp_path / "afile").write_text("x")
    for opt, target in [("--report", tmp_path / "afile" / "r.html"), ("--report", tmp_path),
                        ("--plot", tmp_path), ("--plot", tmp_path / "afile" / "p.png"),
                        ("--plot", tmp_path / "p.csv")]:
        r = cli("velocity", f, "--position", "position", "--velocity", "velocity", opt, target)
        _one_line_error(r)


def test_shaft_calibrate_out_equal_to_input_is_refused(cli, tmp_path):
    r = cli("simulate", "shaft", "--out", tmp_path, "--seed", "1")
    assert r.code == 0, r.err
    f = tmp_path / "shaft_cal.csv"
    before = _digest(f)
    r = cli("shaft", "calibrate", f, "--angle", "angle", "--accel", "accel", "--out", f)
    _one_line_error(r)
    assert _digest(f) == before


def test_triaxial_calibrate_out_equal_to_input_is_refused(cli, tmp_path):
    r = cli("simulate", "magnetometer", "--out", tmp_path, "--motion", "sphere", "--seed", "1")
    assert r.code == 0, r.err
    f = tmp_path / "magnetometer.csv"
    before = _digest(f)
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--out", f)
    _one_line_error(r)
    assert _digest(f) == before


def test_api_may_rewrite_a_file_it_read(tmp_path):
    # Outside a command the guard only checks folders: a script may update its own file.
    from senscal.io import read_recording

    f = _sine(tmp_path / "v.csv")
    rec = read_recording(f)
    write_recording(rec, f)
    assert read_recording(f).names == rec.names


def test_batch_out_equal_to_an_input_is_refused_before_running(cli, tmp_path):
    f = _sine(tmp_path / "v.csv")
    before = _digest(f)
    r = cli("batch", "fit", f, "--out", f, "--workers", "1")
    _one_line_error(r)
    assert _digest(f) == before


def test_batch_malformed_scheduler_address_is_a_one_line_error(cli, tmp_path):
    f = _sine(tmp_path / "v.csv")
    _one_line_error(cli("batch", "fit", f, "--scheduler", "nonsense"))


@pytest.mark.parametrize("cmd", [["velocity", "--position", "position", "--velocity", "velocity"],
                                 ["linearity", "--output", "velocity", "--input-amplitudes", "1,2,3", "--freq", "5"]])
def test_same_recording_twice_is_refused(cli, tmp_path, cmd):
    # Counted twice it would shrink the reported spread of the points: a silently wrong uncertainty.
    a = _sine(tmp_path / "a.csv")
    b = _sine(tmp_path / "b.csv", f=6.0)
    files = [a, tmp_path / "." / "a.csv"] + ([b] if cmd[0] == "linearity" else [])
    r = cli(cmd[0], *files, *cmd[1:])
    _one_line_error(r)
    assert "more than once" in r.err


def test_batch_job_plot_shared_by_several_recordings_is_refused(cli, tmp_path):
    # Each task wrote the same --plot file in turn: the last one silently won.
    a = _sine(tmp_path / "a.csv")
    b = _sine(tmp_path / "b.csv")
    r = cli("batch", "velocity", a, b, "--position", "position", "--velocity", "velocity",
            "--plot", tmp_path / "v.png", "--workers", "1")
    _one_line_error(r)
    assert not (tmp_path / "v.png").exists()


def test_batch_job_report_onto_its_recording_is_refused(cli, tmp_path):
    a = _sine(tmp_path / "a.csv")
    before = _digest(a)
    r = cli("batch", "velocity", a, "--position", "position", "--velocity", "velocity", "--report", a)
    _one_line_error(r)
    assert _digest(a) == before


def test_run_one_protects_the_recording_of_its_job(tmp_path):
    # Inside a worker the job's own input is protected too.
    from senscal.batch.core import run_one

    import senscal.jobs
    from senscal.io.guard import check_output, write_text

    def job_writing_onto_its_input(name, source, opts=None):
        write_text(check_output(source), "overwritten")  # a job that writes an output onto its recording

    a = _sine(tmp_path / "a.csv")
    before = _digest(a)
    mp = pytest.MonkeyPatch()
    mp.setattr(senscal.jobs, "run", job_writing_onto_its_input)
    try:
        row = run_one("velocity", str(a))
    finally:
        mp.undo()
    assert not row.ok and "input" in row.error
    assert _digest(a) == before
