"""``senscal drift --state``: daily files, a killed run, refusals, standard input in chunks (issue 18 item 2)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

from senscal.io import Recording, read_recording, write_recording

OPTS = ["--preset", "redundant", "--trusted", "ref", "--covariate", "temperature", "--covariate-reference", "20",
        "--window", "12", "--no-compare"]


@pytest.fixture(scope="module")
def days(tmp_path_factory):
    """Three daily files cut from one simulated record (5-min samples, ramp from day 1.5)."""
    from senscal.simulate.drift import simulate_drift

    d = tmp_path_factory.mktemp("days")
    rec, _ = simulate_drift(days=3.0, dt=300.0, seed=3, ramp_start_day=1.5)
    write_recording(rec, d / "all.csv")
    for k in range(3):
        keep = (rec.time >= k * 86400) & (rec.time < (k + 1) * 86400)
        write_recording(Recording({c: rec[c][keep] for c in rec.names}, t=rec.time[keep]), d / f"day{k + 1}.csv")
    return d


def _senscal(*args, stdin=None, **kw):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in [os.path.join(os.path.dirname(__file__), "..", "..",
                                                                                "src"), os.environ.get("PYTHONPATH")]
                                                           if p))
    return subprocess.run([sys.executable, "-m", "senscal", *map(str, args)], input=stdin, capture_output=True,
                          text=True, env=env, timeout=600, **kw)


def test_daily_files_equal_one_stream(days, tmp_path, cli):
    """Day by day with --state == the three days piped through one process (first chunk = day 1)."""
    state = tmp_path / "state.json"
    docs = []
    for k in (1, 2, 3):
        extra = ["--flush"] if k == 3 else []
        r = cli("drift", days / f"day{k}.csv", *OPTS, "--state", state, "--out", tmp_path / f"c{k}.csv", "--json",
                *extra)
        assert r.code == 0, r.err
        docs.append(json.loads(r.out))
    assert [d["state"]["how"] for d in docs] == ["started", "continued", "continued"]
    assert docs[1]["noise"]["drift_noise_std"]["estimated"] is False  # kept from the state
    assert docs[0]["noise"]["drift_noise_std"]["value"] == docs[2]["noise"]["drift_noise_std"]["value"]
    assert docs[2]["state"]["pending"] == 0 and docs[2]["state"]["n_output_total"] == docs[2]["state"]["n_samples_total"]
    daily = pd.concat([pd.read_csv(tmp_path / f"c{k}.csv") for k in (1, 2, 3)], ignore_index=True)
    assert daily["t"].is_monotonic_increasing and len(daily) == sum(
        len(read_recording(days / f"day{k}.csv").time) for k in (1, 2, 3))

    text = "".join(line for k in (1, 2, 3)
                   for line in (days / f"day{k}.csv").read_text().splitlines(keepends=True)[(k > 1):])
    n_day1 = len(read_recording(days / "day1.csv").time)
    r = _senscal("drift", "-", *OPTS, "--state", tmp_path / "pipe.json", "--chunk-size", n_day1, "--flush",
                 stdin=text)
    assert r.returncode == 0, r.stderr
    piped = pd.read_csv(pd.io.common.StringIO(r.stdout))
    assert list(piped.columns) == list(daily.columns)
    np.testing.assert_allclose(piped.values, daily.values, rtol=1e-12, atol=1e-12)


def test_fit_levels_refits_and_a_new_drift_is_named(days, tmp_path, cli):
    """Day 1 is quiet, the ramp starts on day 2: kept levels -> model-inadequate; --fit-levels follows the ramp."""
    kept, refit = tmp_path / "kept.json", tmp_path / "refit.json"
    for s in (kept, refit):
        assert cli("drift", days / "day1.csv", *OPTS, "--state", s).code == 0
    a = cli("drift", days / "day2.csv", *OPTS, "--state", kept, "--json")
    b = cli("drift", days / "day2.csv", *OPTS, "--state", refit, "--fit-levels", "--json")
    assert a.code == b.code == 0
    da, db = json.loads(a.out), json.loads(b.out)
    assert any(w.startswith("model-inadequate") for w in da["warnings"])
    assert db["state"]["how"] == "refitted" and db["noise"]["drift_noise_std"]["estimated"] is True
    assert cli("drift", days / "day2.csv", *OPTS, "--state", tmp_path / "k2.json", "--strict").code in (0, 3)


def test_refusals_leave_the_state_untouched(days, tmp_path, cli):
    state = tmp_path / "s.json"
    assert cli("drift", days / "day1.csv", *OPTS, "--state", state).code == 0
    assert cli("drift", days / "day2.csv", *OPTS, "--state", state).code == 0
    before = state.read_bytes()
    cases = [
        (["drift", days / "day1.csv", *OPTS, "--state", state], "time going backwards"),  # yesterday again
        (["drift", days / "day3.csv", "--preset", "redundant", "--channels", "ref,drift", "--trusted", "ref",
          "--window", "12", "--state", state], "another set-up"),
        (["drift", days / "day3.csv", *OPTS[:-3], "--window", "5", "--state", state], "--window 12"),
        (["drift", days / "day3.csv", *OPTS, "--smooth", "--state", state], "either --window or --smooth"),
        (["drift", days / "day3.csv", *OPTS, "--state", tmp_path / "s.txt"], "extension"),
        (["drift", days / "day3.csv", *OPTS, "--fit-levels"], "for --state runs"),
        (["batch", "drift", days / "day3.csv", *OPTS, "--state", state], "once per file"),
    ]
    for args, words in cases:
        r = cli(*args)
        assert r.code == 2, (args, r.err)
        assert words in r.err and len(r.err.strip().splitlines()) == 1 and "Traceback" not in r.err
    assert state.read_bytes() == before
    (tmp_path / "bad.json").write_text("{not json")
    r = cli("drift", days / "day3.csv", *OPTS, "--state", tmp_path / "bad.json")
    assert r.code == 2 and "not valid JSON" in r.err


def test_killed_run_leaves_the_previous_state(days, tmp_path):
    """A run killed while it works (before or during the state write) leaves yesterday's state as it was."""
    from senscal.simulate.drift import simulate_drift

    state = tmp_path / "s.json"
    r = _senscal("drift", days / "day1.csv", *OPTS, "--state", state)
    assert r.returncode == 0, r.stderr
    before = state.read_bytes()
    # A long file continuing day 1, so that the run is still busy when killed.
    rec, _ = simulate_drift(days=15.0, dt=60.0, seed=9)
    keep = rec.time >= 86400
    write_recording(Recording({c: rec[c][keep] for c in rec.names}, t=rec.time[keep]), tmp_path / "long.csv")
    killed_at = []
    for delay in (1.5, 4.0):
        env = dict(os.environ, PYTHONPATH=os.path.join(os.path.dirname(__file__), "..", "..", "src"))
        p = subprocess.Popen([sys.executable, "-m", "senscal", "drift", tmp_path / "long.csv", *OPTS, "--state", state,
                              "--fit-levels"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(delay)
        if p.poll() is None:
            p.send_signal(signal.SIGKILL)
            killed_at.append(delay)
        p.wait(timeout=60)
        assert state.read_bytes() == before
        if p.returncode == 0:  # finished before the kill: the next kill would see the new state
            break
    assert killed_at, "every run finished before it could be killed; make the file longer"
    r = _senscal("drift", tmp_path / "long.csv", *OPTS, "--state", state)  # and the state still continues
    assert r.returncode == 0, r.stderr


def test_stdin_with_a_state_refuses_other_outputs(tmp_path, cli):
    r = cli("drift", "-", "--preset", "known", "--state", tmp_path / "s.json", "--json")
    assert r.code == 2 and "standard output" in r.err


def test_stdin_without_a_state_is_one_pass(tmp_path):
    """Without --state, '-' is read whole, as any file: the document of the same file."""
    from senscal.simulate.drift import simulate_drift_batch

    d = simulate_drift_batch(1, seed=4, n=120, channels=("g",), trusted=(), signal="known", noise=0.1)
    write_recording(Recording({"g": d["y"][0, 0]}, t=d["t"]), tmp_path / "g.csv")
    a = _senscal("drift", tmp_path / "g.csv", "--preset", "known", "--no-compare", "--json")
    b = _senscal("drift", "-", "--preset", "known", "--no-compare", "--json", stdin=(tmp_path / "g.csv").read_text())
    assert a.returncode == b.returncode == 0, a.stderr + b.stderr
    da, db = json.loads(a.stdout), json.loads(b.stdout)
    assert da["channels"] == db["channels"] and da["noise"] == db["noise"]


def test_stdin_is_read_line_by_line(tmp_path):
    """A pipe that stays open: corrected rows appear before the input ends (tail -f)."""
    from senscal.simulate.drift import simulate_drift_batch

    d = simulate_drift_batch(1, seed=4, n=80, channels=("g",), trusted=(), signal="known", noise=0.1)
    lines = ["t,g\n"] + [f"{float(t)!r},{float(v)!r}\n" for t, v in zip(d["t"], d["y"][0, 0])]
    env = dict(os.environ, PYTHONPATH=os.path.join(os.path.dirname(__file__), "..", "..", "src"))
    p = subprocess.Popen([sys.executable, "-m", "senscal", "drift", "-", "--preset", "known", "--state",
                          tmp_path / "s.npz", "--chunk-size", "40", "--no-compare"], env=env, stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        p.stdin.write("".join(lines[:41]))  # header + the first chunk, and the pipe stays open
        p.stdin.flush()
        header = p.stdout.readline()
        first = p.stdout.readline()
        assert header.startswith("t,g_corrected,g_bias,g_bias_std") and float(first.split(",")[0]) == d["t"][0]
        p.stdin.write("".join(lines[41:]))
        p.stdin.close()
        rest = p.stdout.read()
        assert p.wait(timeout=120) == 0, p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
    assert len(rest.strip().splitlines()) == 79
    from senscal.drift.stream import TrackerState

    assert TrackerState.load(tmp_path / "s.npz").n_samples == 80
