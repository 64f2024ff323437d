"""``-`` for standard input and output: fit, triaxial apply and simulate in a pipe."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from senscal.io import Recording, read_recording, write_recording


@pytest.fixture
def stdin(monkeypatch):
    """Feed bytes to standard input of the in-process CLI."""

    def feed(data: bytes) -> None:
        monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data), encoding="utf-8"))

    return feed


@pytest.fixture
def sine(tmp_path):
    from senscal.simulate.sine import simulate_sine

    rec, _ = simulate_sine(n_channels=2, fs=1000.0, duration=1.0, frequency=12.5, noise=0.05, seed=7)
    return write_recording(rec, tmp_path / "sine.csv")


def test_fit_reads_csv_from_stdin_with_the_same_result(cli, stdin, sine):
    from_file = json.loads(cli("fit", sine, "--json").out)
    stdin(sine.read_bytes())
    r = cli("fit", "-", "--json")
    assert r.code == 0, r.err
    piped = json.loads(r.out)
    assert piped["channels"] == from_file["channels"]


@pytest.mark.parametrize("fmt,suffix", [("parquet", ".parquet"), ("hdf5", ".h5"), ("npz", ".npz")])
def test_binary_formats_on_stdin_ask_for_a_file(cli, stdin, sine, tmp_path, fmt, suffix):
    other = write_recording(read_recording(sine), tmp_path / f"sine{suffix}")
    stdin(other.read_bytes())
    r = cli("fit", "-", "--json")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1
    assert "only CSV text can be piped in" in r.err and r.out == ""


def test_empty_stdin_and_errors_name_standard_input(cli, stdin):
    stdin(b"")
    r = cli("fit", "-")
    assert r.code == 2 and "empty" in r.err and "standard input" in r.err
    stdin(b"t,x\n0,1\n1,oops\n")
    r = cli("fit", "-")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1
    assert "senscal-stdin" not in r.err  # the spool file is not the user's business


def test_triaxial_apply_writes_csv_to_stdout_and_messages_to_stderr(cli, tmp_path):
    from senscal.triaxial import TriaxialCalibration

    cal = TriaxialCalibration(model="offsets", method="ml", matrix=np.eye(3), offsets=np.array([1.0, 2.0, 3.0]),
                              field=1.0)
    params = cal.save(tmp_path / "p.json")
    data = {c: np.arange(5.0) * (i + 1) for i, c in enumerate("xyz")}
    f = write_recording(Recording(data, fs=2.0), tmp_path / "r.csv")
    r = cli("triaxial", "apply", f, "--params", params, "--channels", "x,y,z", "--out", "-")
    assert r.code == 0, r.err
    (tmp_path / "back.csv").write_text(r.out)
    back = read_recording(tmp_path / "back.csv")  # stdout is the recording and nothing else
    for i, c in enumerate("xyz"):
        np.testing.assert_allclose(back[c], data[c] - (i + 1.0))
    assert "samples corrected" in r.err
    # --json and the recording cannot share stdout.
    r = cli("triaxial", "apply", f, "--params", params, "--channels", "x,y,z", "--out", "-", "--json")
    assert r.code == 2 and "both go to standard output" in r.err


def test_triaxial_params_through_a_pipe(cli, stdin, tmp_path):
    from senscal.triaxial import TriaxialCalibration

    cal = TriaxialCalibration(model="offsets", method="ml", matrix=np.eye(3), offsets=np.array([1.0, 2.0, 3.0]),
                              field=1.0)
    text = cal.save(tmp_path / "p.json").read_bytes()
    f = write_recording(Recording({c: np.arange(4.0) for c in "xyz"}, fs=1.0), tmp_path / "r.csv")
    stdin(text)
    r = cli("triaxial", "apply", f, "--params", "-", "--channels", "x,y,z", "--out", tmp_path / "o.csv")
    assert r.code == 0, r.err
    np.testing.assert_allclose(read_recording(tmp_path / "o.csv")["z"], np.arange(4.0) - 3.0)
    stdin(cal.save(tmp_path / "p.h5").read_bytes())
    r = cli("triaxial", "apply", f, "--params", "-", "--channels", "x,y,z", "--out", tmp_path / "o.csv")
    assert r.code == 2 and "HDF5, which needs a file" in r.err


def test_simulate_to_stdout_and_folders_under_dash_are_refused(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = cli("simulate", "sine", "--out", "-", "--seed", "3", "--channels", "1")
    assert r.code == 0, r.err
    assert r.out.startswith("t,") and "standard output" in r.err
    assert not Path("-").exists()
    r = cli("simulate", "magnetometer", "--out", "-", "--seed", "1")
    assert r.code == 2 and "takes one file, not a folder" in r.err and not Path("-").exists()


def test_registry_export_to_stdout(cli, tmp_path):
    db = tmp_path / "r.sqlite"
    assert cli("registry", "add", "SN-1", "--kind", "accelerometer", "--db", db).code == 0
    r = cli("registry", "export", "-", "--db", db)
    assert r.code == 0, r.err
    assert [s["serial"] for s in json.loads(r.out)["sensors"]] == ["SN-1"]


def test_a_real_pipe_simulate_into_fit(tmp_path):
    """The shell's pipe, not a monkeypatched stream: simulate -> fit -."""
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2] / "src"))
    sim = subprocess.run([sys.executable, "-m", "senscal", "simulate", "sine", "--out", "-", "--seed", "5",
                          "--channels", "2"], capture_output=True, env=env, cwd=tmp_path, timeout=300)
    assert sim.returncode == 0, sim.stderr
    fit = subprocess.run([sys.executable, "-m", "senscal", "fit", "-", "--json"], input=sim.stdout,
                         capture_output=True, env=env, cwd=tmp_path, timeout=300)
    assert fit.returncode == 0, fit.stderr
    (tmp_path / "sine.csv").write_bytes(sim.stdout)
    direct = subprocess.run([sys.executable, "-m", "senscal", "fit", "sine.csv", "--json"], capture_output=True,
                            env=env, cwd=tmp_path, timeout=300)
    assert json.loads(fit.stdout)["channels"] == json.loads(direct.stdout)["channels"]


def test_side_files_from_stdin_and_only_one_input_per_pipe(cli, stdin, tmp_path):
    from senscal.triaxial import TriaxialCalibration

    hist = tmp_path / "sim"
    assert cli("simulate", "registry", "--out", hist, "--seed", "2").code == 0
    stdin((hist / "history.json").read_bytes())
    r = cli("registry", "import", "-", "--db", tmp_path / "r.sqlite", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["calibrations"] == 7
    params = TriaxialCalibration(model="offsets", method="ml", matrix=np.eye(3), offsets=np.zeros(3),
                                 field=1.0).save(tmp_path / "p.json")
    stdin(params.read_bytes())
    r = cli("triaxial", "apply", "-", "--params", "-", "--channels", "x,y,z", "--out", tmp_path / "o.csv")
    assert r.code == 2 and "both read standard input" in r.err
