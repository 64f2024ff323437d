"""The CLI's last line of defence: one line for a bug (exit 1), for an OS failure on a path (exit 2), --debug."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import senscal.io as sio
from senscal.io import Recording, write_recording


@pytest.fixture
def sine(tmp_path):
    t = np.arange(200) / 200.0
    return write_recording(Recording(channels={"x": np.sin(2 * np.pi * 5 * t)}, t=t), tmp_path / "s.csv")


def _boom(*a, **k):
    raise RuntimeError("boom\nsecond line")


def test_unexpected_exception_is_one_line_exit_1(cli, sine, monkeypatch):
    monkeypatch.setattr(sio, "read_recording", _boom)
    r = cli("fit", sine)
    assert r.code == 1
    assert r.err == ("senscal: internal error (RuntimeError: boom second line); please report it; "
                     "rerun with --debug for the traceback\n")


@pytest.mark.parametrize("how", ["flag", "flag-after", "env"])
def test_debug_shows_the_traceback(cli, sine, monkeypatch, how):
    monkeypatch.setattr(sio, "read_recording", _boom)
    args = {"flag": ("--debug", "fit", sine), "flag-after": ("fit", sine, "--debug"), "env": ("fit", sine)}[how]
    if how == "env":
        monkeypatch.setenv("SENSCAL_DEBUG", "1")
    with pytest.raises(RuntimeError, match="boom"):
        cli(*args)


def test_os_error_on_a_user_path_is_exit_2_naming_it(cli, sine, monkeypatch):
    def denied(*a, **k):
        raise PermissionError(13, "Permission denied", "/data/run1.csv")

    monkeypatch.setattr(sio, "read_recording", denied)
    r = cli("fit", sine)
    assert (r.code, r.err) == (2, "senscal: error: /data/run1.csv: permission denied\n")


def test_usage_errors_are_one_line(cli):
    r = cli("triaxial", "calibrate", "x.csv")
    assert r.code == 2
    assert r.err == "senscal: error: Missing option '--channels'; see 'senscal triaxial calibrate --help'\n"
    r = cli("fit", "x.csv", "--freq", "fast")
    assert r.code == 2 and len(r.err.splitlines()) == 1 and "'--freq'" in r.err


@pytest.mark.parametrize("args, match", [
    (("simulate", "sine", "--seed", "-1"), "--seed must be a whole number"),
    (("simulate", "registry", "--seed", "-3"), "--seed must be a whole number"),
    # refused by the machine's memory bound before the sample count is formed (issue 32: counts bounded)
    (("simulate", "sine", "--duration", "1e15"), "more than fits in this machine's memory"),
    (("simulate", "sine", "--fs", "1e308"), "samples per channel"),
    (("simulate", "shaft", "--fs", "1e308"), "samples per channel"),
    (("simulate", "sine", "--fs", "nan"), "--fs must be a positive, finite number"),
    (("simulate", "drift", "--samples", "10000000000"), "--samples"),
])
def test_simulator_argument_edges(cli, tmp_path, args, match):
    r = cli(*args, "--out", tmp_path / "o")
    assert r.code == 2, r.err
    assert len(r.err.splitlines()) == 1 and match in r.err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_real_entry_point_in_a_pipe_is_one_line(tmp_path, sine):
    # stderr is a pipe here (not a terminal): no Rich boxes or wrapping, one line per message.
    code = ("import senscal.io as c\n"
            "def boom(*a, **k): raise KeyError('k' * 300)\n"
            "c.read_recording = boom\n"
            "from senscal.cli import main\n"
            f"main(['fit', {str(sine)!r}])\n")
    env = {**os.environ, "COLUMNS": "40"}
    env.pop("SENSCAL_DEBUG", None)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 1
    assert len(p.stderr.splitlines()) == 1 and p.stderr.startswith("senscal: internal error (KeyError:")
    p = subprocess.run([sys.executable, "-m", "senscal", "fit", str(tmp_path / "missing.csv")], capture_output=True,
                       text=True, env=env, timeout=300)
    assert p.returncode == 2 and p.stderr == f"senscal: error: file not found: {tmp_path / 'missing.csv'}\n"
