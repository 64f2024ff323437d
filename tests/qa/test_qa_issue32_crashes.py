"""Issue 32 item 7: the campaign's internal errors and hangs, each now one line naming the problem (exit 2).

The same command lines run under the fuzz harness' classifier (time limit,
inputs unchanged) in tests/fuzz/test_fuzz_issue32.py; here the message says
what is wrong and how to fix it.
"""

from __future__ import annotations

import numpy as np
import pytest

from senscal.io import Recording, write_recording


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("crashes")
    rng = np.random.default_rng(5)
    t = np.arange(200, dtype=float)
    out = {"huge": write_recording(Recording({"x": rng.uniform(1, 9, t.size) * 1e300}, t=t), d / "huge.csv"),
           "big": write_recording(Recording({"x": rng.uniform(1, 9, t.size) * 1e140}, t=t), d / "big.csv")}
    v = rng.normal(size=(150, 3))
    v = 50.0 * v / np.linalg.norm(v, axis=1)[:, None] + [3.0, -2.0, 1.0]
    mag = write_recording(Recording(dict(zip("xyz", v.T)), fs=10.0), d / "mag.csv")
    out["mag"] = mag
    v[5, 0] = 1e308
    out["mag_huge"] = write_recording(Recording(dict(zip("xyz", v.T)), fs=10.0), d / "mag_huge.csv")
    out["dir"] = d
    return out


def _one_line(r, code=2, *words):
    lines = [ln for ln in r.err.splitlines() if ln.strip() and not ln.startswith("warning:")]
    assert r.code == code and len(lines) == 1 and lines[0].startswith("senscal: error:"), r.err
    assert "internal error" not in r.err, r.err
    for w in words:
        assert w in r.err, r.err


def test_allan_on_values_that_overflow_the_variance(cli, files):
    _one_line(cli("allan", files["huge"], "-c", "x"), 2, "overflows", "rescale")
    assert cli("allan", files["big"], "-c", "x").code == 0  # 1e140 still squares without overflow


def test_triaxial_apply_overflowing_correction(cli, files, tmp_path):
    r = cli("triaxial", "calibrate", files["mag"], "--channels", "x,y,z", "--out", tmp_path / "p.json")
    assert r.code == 0, r.err
    r = cli("triaxial", "apply", files["mag_huge"], "--params", tmp_path / "p.json", "--channels", "x,y,z",
            "--out", tmp_path / "a.csv")
    _one_line(r, 2, "overflows")
    assert not (tmp_path / "a.csv").exists()


@pytest.mark.parametrize("cmd", [
    ["fit-array", "{huge}", "--dataset", "y", "--out", "{o}/f.csv", "--workers", "2147483648"],
    ["batch", "fit", "{huge}", "--workers", "2147483648"],
    ["drift-fleet", "{o}", "--config", "{huge}", "--workers", "2147483648"],
])
def test_worker_counts_are_bounded_by_the_machine(cli, files, tmp_path, cmd):
    from senscal.cli import _limits

    r = cli(*[a.format(huge=files["huge"], o=tmp_path) for a in cmd])
    _one_line(r, 2, "--workers", f"at most {_limits.max_workers()} worker processes", "cores")


@pytest.mark.parametrize("cmd", [
    ["simulate", "sine", "--channels", "2147483648"],
    ["simulate", "fleet", "--channels", "2147483648"],
    ["simulate", "sine", "--channels", "4000000", "--fs", "1e4", "--duration", "100"],
])
def test_simulated_sizes_are_bounded_by_memory(cli, tmp_path, cmd):
    r = cli(*cmd, "--out", tmp_path / "s")
    _one_line(r, 2, "memory")
    assert not (tmp_path / "s").exists()


def test_limits_come_from_the_machine():
    import os

    from senscal.cli import _limits

    assert 1 <= _limits.cores() <= (os.cpu_count() or 1)
    with open("/proc/meminfo") as fh:
        total = int(next(ln for ln in fh if ln.startswith("MemTotal:")).split()[1]) * 1024
    # psutil and /proc/meminfo read the same kernel figure (a page or two apart at most).
    assert abs(_limits.memory_bytes() - total) <= 0.01 * total
    assert _limits.max_workers() <= _limits.WORKERS_PER_CORE * _limits.cores()
    assert _limits.max_workers() * _limits.WORKER_BYTES <= _limits.memory_bytes()


def test_shaft_window_longer_than_the_record(cli, tmp_path):
    r = cli("simulate", "shaft", "--out", tmp_path, "--seed", "1", "--fs", "200", "--cal-duration", "6",
            "--test-duration", "3")
    assert r.code == 0, r.err
    for w in ("1e308", "100"):
        _one_line(cli("shaft", "calibrate", tmp_path / "shaft_cal.csv", "--angle", "angle", "--accel", "accel",
                      "--window", w), 2, "longer than the record")


@pytest.fixture(scope="module")
def drift(tmp_path_factory):
    import contextlib
    import io

    from senscal.cli import main

    d = tmp_path_factory.mktemp("drift")
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        with contextlib.suppress(SystemExit):
            main(["simulate", "drift", "--out", str(d), "--seed", "1", "--samples", "200"])
    f = d / "drift.csv"
    chans = [h for h in f.read_text().splitlines()[0].split(",") if h not in ("t", "temperature")]
    return f, chans


@pytest.mark.parametrize("ref", ["-1e308", "1e200"])
def test_drift_covariate_reference_that_overflows(cli, drift, ref):
    f, ch = drift
    r = cli("drift", f, "--preset", "redundant", "--trusted", ch[0], "--channels", ",".join(ch[:2]), "--covariate",
            "temperature", "--covariate-reference", ref, "--no-compare")
    _one_line(r, 2, "--covariate-reference")


@pytest.mark.parametrize("signal,word", [
    ("{kind: random_walk, level: abc}", "signal level must be a number"),
    ("{kind: gauss_markov, tau: x1, level: 1}", "signal tau must be a number"),
    ("{kind: known, mean: '1.5'}", "signal mean must be a number"),
    ("{kind: matrix, F: [[abc]], Q: [[1]], H: [[1]]}", "signal F must be a matrix of numbers"),
])
def test_drift_model_yaml_with_a_string_for_a_number(cli, drift, tmp_path, signal, word):
    f, ch = drift
    m = tmp_path / "m.yaml"
    m.write_text(f"channels: [{ch[0]}, {ch[1]}]\ntrusted: [{ch[0]}]\nsignal: {signal}\n"
                 f"biases:\n  - {{channel: {ch[1]}}}\n")
    _one_line(cli("drift", f, "--preset", "model", "--model", m, "--no-compare"), 2, word)


@pytest.mark.parametrize("bias,word", [("reference: abc", "bias reference"), ("level: '1e-3'", "bias level")])
def test_drift_model_yaml_bias_and_noise_numbers(cli, drift, tmp_path, bias, word):
    f, ch = drift
    m = tmp_path / "m.yaml"
    m.write_text(f"channels: [{ch[0]}, {ch[1]}]\ntrusted: [{ch[0]}]\nsignal: {{kind: random_walk}}\n"
                 f"noise_std: {{{ch[0]}: 0.05}}\nbiases:\n  - {{channel: {ch[1]}, {bias}}}\n")
    _one_line(cli("drift", f, "--preset", "model", "--model", m, "--no-compare"), 2, word)
    m.write_text(f"channels: [{ch[0]}, {ch[1]}]\ntrusted: [{ch[0]}]\nsignal: {{kind: random_walk}}\n"
                 f"noise_std: {{{ch[0]}: abc}}\nbiases:\n  - {{channel: {ch[1]}}}\n")
    _one_line(cli("drift", f, "--preset", "model", "--model", m, "--no-compare"), 2, "noise_std")


def test_damaged_tdms_is_one_line_without_library_log_lines(cli, tmp_path):
    t = np.arange(400) / 400.0
    good = write_recording(Recording({"x": np.sin(2 * np.pi * 10 * t)}, t=t), tmp_path / "s.tdms").read_bytes()
    for cut in (len(good) // 2, len(good) - 10, 40):
        (tmp_path / "bad.tdms").write_bytes(good[:cut])
        r = cli("fit", tmp_path / "bad.tdms", "--freq", "10")
        assert "nptdms" not in r.err and "WARNING" not in r.err, r.err
        if r.code:
            _one_line(r, 2)
