"""Drift correction speed against a plain CSV read and filterpy, same data, one run.

    python benchmarks/bench_drift.py [--days 70] [--dt 60] [--ml-only] [--samples 1e4,1e5,1e6]
                                     [--channels 1,10,100] [--budget 2e6]
    python benchmarks/bench_drift.py --job FILE [--job-channels gx,gy,gz] [--runs 3]

Simulates three drifting sensors (default 70 days at 1-min samples,
~1e5 samples), then times: reading the CSV (the floor any tool pays),
the augmented filter with given noise levels (redundant preset with the
temperature covariate: 5 states, time-varying H), the same with a 60-sample
window, the RTS smoother, the maximum-likelihood noise estimation, and
filterpy's loop on the same augmented model.

Then (``--ml-only``: only) the noise-level maximum likelihood against one
filter pass, per channel and model (issue 30): gyros at rest (preset
``known``: a random-walk bias and white noise per channel, 100 Hz), for each
record length and channel count, with and without the model comparison, the
CPU time of the estimation per channel and model, the CPU time of one
filter pass over the same channel with the estimated levels, and their
ratio.  The estimation is the job's own first step (the asked model's
search and its levels' curvature; a compared model's search only, as the
comparison needs only its likelihood).  The channels of a known quantity are independent blocks, so the
estimation per channel does not depend on how many there are; above
``--budget`` samples x channels the per-channel time is measured on a sample
of the channels (the ``timed`` column).  CPU time (``time.process_time``),
not wall time: the machine this runs on is shared.

``--job FILE``: the issue-30 command, ``senscal drift FILE --preset known
--channels ... --json``, run ``--runs`` times in a fresh interpreter each
(imports included), printing its wall and CPU time and its *critical path
on two workers*: the main thread's CPU time plus, for every fit, the
makespan of its channels' search CPU times on two workers (blocks taken in
order by the first free worker, as the job's thread pool does).  That is
what two idle cores would take, whatever the load of the machine it runs
on.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--days", type=float, default=70.0)
    ap.add_argument("--dt", type=float, default=60.0)
    ap.add_argument("--ml-only", action="store_true", help="only the ML-per-channel table")
    ap.add_argument("--samples", default="1e4,1e5,1e6")
    ap.add_argument("--channels", default="1,10,100")
    ap.add_argument("--budget", type=float, default=2e6, help="samples x channels timed per row")
    ap.add_argument("--job", help="time the drift job on this file instead (see the module doc)")
    ap.add_argument("--job-channels", default="gx,gy,gz")
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    if args.job:
        job_table(args)
        return
    if not args.ml_only:
        speed(args)
    ml_table(args)


def speed(args) -> None:

    from senscal.drift import DriftSetup, augmented_model, correct_drift, redundant_setup
    from senscal.drift.core import _starting_levels
    from senscal.io import read_recording, write_recording
    from senscal.simulate.drift import simulate_drift

    rec, truth = simulate_drift(days=args.days, dt=args.dt, seed=0)
    chans = ["ref", "drift", "thermal"]
    T = rec.n_samples
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "drift.csv"
        write_recording(rec, path)
        t0 = time.perf_counter()
        rec = read_recording(path)
        t_read = time.perf_counter() - t0
    y, t = rec.data(chans), rec.time
    cov = {"temperature": rec["temperature"]}
    base = redundant_setup(chans, trusted=["ref"], covariate="temperature")
    c = cov["temperature"] - cov["temperature"].mean()
    levels = _starting_levels(base, y, args.dt, float(t[-1]), {"temperature": c})
    given = DriftSetup(base.channels, base.signal.__class__(level=levels["signal_rate_std"]),
                       tuple(b.__class__(b.channel, b.covariate, b.reference, b.dynamics, levels[b.level_name], b.tau)
                             for b in base.biases),
                       noise_std={ch: levels[f"{ch}_noise_std"] for ch in chans}, trusted=base.trusted)
    small = max(1000, T // 100)
    correct_drift(given, y[:, :small], t[:small], {"temperature": cov["temperature"][:small]}, estimate=False)
    correct_drift(given, y[:, :small], t[:small], {"temperature": cov["temperature"][:small]}, estimate=False,
                  window=5)

    def timed(**kw):
        t0 = time.perf_counter()
        correct_drift(given, y, t, cov, estimate=False, **kw)
        return time.perf_counter() - t0

    t_filter = timed()
    t_window = timed(window=60)
    t_smooth = timed(smooth=True)
    n_ml = min(T, 20000)
    t0 = time.perf_counter()
    correct_drift(base, y[:, :n_ml], t[:n_ml], {"temperature": cov["temperature"][:n_ml]})
    t_ml = time.perf_counter() - t0

    from filterpy.kalman import KalmanFilter

    model = augmented_model(given, np.diff(t, prepend=t[0] - args.dt), levels, {"temperature": c})
    kf = KalmanFilter(dim_x=model.n_states, dim_z=3)
    kf.F, kf.Q, kf.R = model.F, model.Q, model.R
    kf.x = np.zeros((model.n_states, 1))
    kf.P = np.eye(model.n_states) * 100.0
    from senscal.kalman import kalman_filter

    kalman_filter(model, y[:, :10] if model.n_steps is None else y)  # compile / load cache
    t0 = time.perf_counter()
    kalman_filter(model, y)
    t_engine = time.perf_counter() - t0
    t0 = time.perf_counter()
    for k in range(T):
        if k > 0:
            kf.predict()
        kf.update(y[:, k], H=model.H[k])
    t_fp = time.perf_counter() - t0

    print(f"Drift correction, 3 sensors + covariate, {T:,} samples (5 augmented states, time-varying H)")
    print(f"  read CSV (floor):                    {t_read:8.3f} s")
    print(f"  filter + CUSUM detection:            {t_filter:8.3f} s   {t_filter / t_read:6.2f}x the CSV read")
    print(f"  window L=60 (fixed lag):             {t_window:8.3f} s   {t_window / t_read:6.2f}x the CSV read")
    print(f"  RTS smoother:                        {t_smooth:8.3f} s   {t_smooth / t_read:6.2f}x the CSV read")
    print(f"  ML noise levels + filter, {n_ml:,} samples: {t_ml:8.3f} s")
    print(f"  senscal engine, filter only:         {t_engine:8.3f} s")
    print(f"  filterpy loop, filter only:          {t_fp:8.3f} s   {t_fp / t_engine:.1f}x the engine's time, "
          f"{t_fp / t_filter:.1f}x senscal's filter + detection")


def _ml(setup, y, t, curvature: bool):
    """The job's noise-level search alone (``correct_drift``'s first step), with or without the curvature."""
    from senscal.drift.adequacy import moment_levels
    from senscal.drift.core import _fit_levels, _moment_levels_start, drift_prior

    dt = np.empty(t.size)
    dt[1:] = np.diff(t)
    dt[0] = dt[1]
    yy = y - setup.signal.mean if setup.signal.kind in ("gauss_markov", "known") else y
    duration = float(t[-1] - t[0])
    x0, P0 = drift_prior(setup, yy, {}, duration)
    given = setup.given_levels()
    start = _moment_levels_start(setup, yy, float(np.median(dt)), duration, {}, moment_levels(yy))
    free = {k: start[k] for k in setup.level_names() if k not in given}
    return _fit_levels(setup, yy, dt, {}, x0, P0, free, given, curvature=curvature)[0]


def ml_table(args) -> None:
    """Noise-level ML per channel and model against one filter pass (issue 30); see the module doc."""

    from senscal.drift import augmented_model, correct_drift, known_setup
    from senscal.drift.core import _alternatives, drift_prior
    from senscal.kalman import kalman_filter
    from senscal.simulate.drift import simulate_drift_batch

    Ts = [int(float(x)) for x in args.samples.split(",")]
    Cs = [int(float(x)) for x in args.channels.split(",")]
    # Warm-up: load every compiled kernel once.
    w = simulate_drift_batch(1, n=500, dt=0.01, channels=("g",), trusted=(), signal="known", seed=0)
    correct_drift(known_setup(["g"]), w["y"][0], w["t"], compare=True)

    print("Noise-level ML vs one filter pass (preset known, random-walk bias + white noise, CPU seconds)")
    head = f"{'samples':>9} {'channels':>8} {'timed':>5} {'compare':>7} {'models':>6} {'ML/ch/model':>12} " \
           f"{'filter/ch':>10} {'ratio':>7}"
    print(head)
    for T in Ts:
        for C in Cs:
            k = int(max(1, min(C, args.budget // T)))
            d = simulate_drift_batch(1, n=T, dt=0.01, channels=tuple(f"g{i}" for i in range(k)), trusted=(),
                                     signal="known", bias="random_walk", bias_rate=0.01, noise=0.1, seed=T + C)
            chans = [f"g{i}" for i in range(k)]
            y, t = d["y"][0], d["t"]
            setup = known_setup(chans)
            for compare in (False, True):
                models = [setup] + ([a for _, a, _ in _alternatives(setup)] if compare else [])
                c0 = time.process_time()
                # What the job runs: the asked model with its levels' uncertainties, the compared ones
                # for their likelihood only.
                fits = [_ml(s, y, t, curvature=(i == 0)) for i, s in enumerate(models)]
                t_ml = (time.process_time() - c0) / (k * len(models))
                # One filter pass over one channel with its estimated levels.
                one = known_setup([chans[0]])
                lv = {p.name: p.value for p in fits[0] if p.name.startswith(chans[0] + "_")}
                x0, P0 = drift_prior(one, y[:1], {}, float(t[-1] - t[0]))
                model = augmented_model(one, np.diff(t, prepend=t[0] - 0.01), lv, x0=x0, P0=P0)
                kalman_filter(model, y[:1, :10])
                reps = max(1, int(2e5 // T))
                c0 = time.process_time()
                for _ in range(reps):
                    kalman_filter(model, y[:1])
                t_f = (time.process_time() - c0) / reps
                print(f"{T:>9,} {C:>8} {k:>5} {'yes' if compare else 'no':>7} {len(models):>6} {t_ml:>12.4f} "
                      f"{t_f:>10.5f} {t_ml / t_f:>6.1f}x", flush=True)


#: Run in a fresh interpreter: the drift job with every block's search timed on its own thread.
_JOB_DRIVER = r"""
import contextlib, io, runpy, sys, threading, time
w0 = time.perf_counter()
import senscal.drift.core as C
import senscal.drift.estimate as E
calls, lock = [], threading.Lock()
est, fit = E.estimate_levels, C._fit_levels
def timed_est(*a, **k):
    t0 = time.thread_time()
    try:
        return est(*a, **k)
    finally:
        with lock:
            calls[-1].append(time.thread_time() - t0)
def timed_fit(*a, **k):
    calls.append([])
    return fit(*a, **k)
C.estimate_levels, C._fit_levels = timed_est, timed_fit
sys.argv = ["senscal", "drift", sys.argv[1], "--preset", "known", "--channels", sys.argv[2], "--json"]
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    try:
        runpy.run_module("senscal", run_name="__main__")
    except SystemExit:
        pass
main_cpu = time.thread_time()
def makespan(blocks, workers=2):
    free = [0.0] * workers
    for b in blocks:
        free[free.index(min(free))] += b
    return max(free)
span = sum(makespan(c) for c in calls)
print(f"{time.perf_counter() - w0:.1f} {time.process_time():.2f} {main_cpu:.2f} {span:.2f}")
"""


def job_table(args) -> None:
    """The drift job on a file: wall, CPU and the critical path on two workers (see the module doc)."""
    import os
    import subprocess
    import sys

    print(f"senscal drift {args.job} --preset known --channels {args.job_channels} --json")
    print(f"{'run':>3} {'load':>5} {'wall s':>7} {'CPU s':>6} {'main thread':>11} {'2-worker fits':>13} "
          f"{'critical path':>13}")
    env = dict(os.environ)
    src = str(Path(__file__).resolve().parent.parent / "src")
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    for i in range(args.runs):
        load = os.getloadavg()[0]
        out = subprocess.run([sys.executable, "-c", _JOB_DRIVER, args.job, args.job_channels], env=env,
                             capture_output=True, text=True, check=True).stdout.split()
        wall, cpu, main_cpu, span = map(float, out[-4:])
        print(f"{i + 1:>3} {load:>5.1f} {wall:>7.1f} {cpu:>6.2f} {main_cpu:>11.2f} {span:>13.2f} "
              f"{main_cpu + span:>13.2f}", flush=True)


if __name__ == "__main__":
    main()
