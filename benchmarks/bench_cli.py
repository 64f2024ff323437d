"""Start-up cost of the command line, as ratios against a plain Python baseline (one run).

Each row runs a command in a fresh interpreter ``--repeat`` times and keeps the
best wall time (the least disturbed by other load on the machine):

- ``senscal --help`` and ``senscal fit --help`` against ``python -c "import typer"``
  (the toolkit the command line is built on: target within 2x);
- ``senscal fit small.csv`` against ``python -c "import numpy, scipy.linalg"`` plus
  the fit itself, timed in-process on the same file (target within 2x);
- a few other commands' ``--help`` and the old eager start (every command module
  imported first) for comparison, against ``python -c pass``.

``--cold-demo`` also times ``senscal demo`` twice with a fresh, empty numba cache
(``NUMBA_CACHE_DIR`` in a temporary folder): the first run is what a user meets on
a fresh install (every kernel the demo uses compiles), the second what they meet
afterwards.

Run: ``python benchmarks/bench_cli.py [--repeat 5] [--cold-demo]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SENSCAL = [sys.executable, "-m", "senscal"]


def best(argv: list[str], repeat: int, env: dict | None = None) -> float:
    """Best wall time (s) of ``repeat`` runs of ``argv``; a failing command stops the benchmark."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = subprocess.run(argv, capture_output=True, check=False, env=env)
        times.append(time.perf_counter() - t0)
        if r.returncode != 0:
            raise SystemExit(f"{' '.join(argv)} failed ({r.returncode}): {r.stderr.decode()[-500:]}")
    return min(times)


def small_csv(folder: Path) -> Path:
    """A 2-channel, 2000-sample sine recording (CSV): the kind of file a user tries first."""
    import numpy as np

    rng = np.random.default_rng(0)
    t = np.arange(2000) / 1000.0
    path = folder / "small.csv"
    data = np.column_stack([t, 2.0 * np.sin(2 * np.pi * 12.5 * t + 0.3) + rng.normal(0, 0.05, t.size),
                            0.5 * np.sin(2 * np.pi * 12.5 * t) + rng.normal(0, 0.05, t.size)])
    np.savetxt(path, data, delimiter=",", header="t,ch1,ch2", comments="", fmt="%.9g")
    return path


def fit_in_process(path: Path, repeat: int) -> float:
    """Best time (s) of the fit job alone (file read + fits), warm, in this process."""
    from senscal.jobs.fit import FitOptions, fit

    fit(path, FitOptions())  # imports and first-call costs are not the fit's
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fit(path, FitOptions())
        times.append(time.perf_counter() - t0)
    return min(times)


def cold_demo() -> tuple[float, float]:
    """(first, second) wall time (s) of ``senscal demo`` on a fresh numba cache."""
    with tempfile.TemporaryDirectory() as d:
        env = {**os.environ, "NUMBA_CACHE_DIR": str(Path(d) / "numba")}
        out = []
        for i in range(2):
            t0 = time.perf_counter()
            r = subprocess.run([*SENSCAL, "demo", "--out", str(Path(d) / f"demo{i}")], capture_output=True, env=env)
            out.append(time.perf_counter() - t0)
            if r.returncode != 0:
                raise SystemExit(f"senscal demo failed: {r.stderr.decode()[-500:]}")
        return out[0], out[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cold-demo", action="store_true", help="also time senscal demo on a fresh numba cache")
    args = ap.parse_args()
    r = args.repeat
    with tempfile.TemporaryDirectory() as d:
        csv = small_csv(Path(d))
        t_pass = best([sys.executable, "-c", "pass"], r)
        t_typer = best([sys.executable, "-c", "import typer"], r)
        t_np = best([sys.executable, "-c", "import numpy, scipy.linalg"], r)
        t_fit = fit_in_process(csv, r)
        rows = [
            ("senscal --help", best([*SENSCAL, "--help"], r), "import typer", t_typer),
            ("senscal fit --help", best([*SENSCAL, "fit", "--help"], r), "import typer", t_typer),
            ("senscal fit small.csv", best([*SENSCAL, "fit", str(csv)], r), "import numpy, scipy.linalg + fit",
             t_np + t_fit),
            ("senscal registry --help", best([*SENSCAL, "registry", "--help"], r), "python -c pass", t_pass),
            ("senscal gfimu --help", best([*SENSCAL, "gfimu", "--help"], r), "python -c pass", t_pass),
            ("eager: all command modules + --help",
             best([sys.executable, "-c", "from senscal.cli import load_commands, main; load_commands(); main(['--help'])"],
                  r), "python -c pass", t_pass),
        ]
    print(f"baselines (best of {r}): python -c pass {t_pass:.3f} s, import typer {t_typer:.3f} s, "
          f"import numpy, scipy.linalg {t_np:.3f} s, fit of small.csv in-process {t_fit * 1e3:.1f} ms")
    print(f"{'command':38s} {'best s':>7s}  {'ratio':>6s}  against")
    for name, t, base_name, base in rows:
        target = "  (target <= 2)" if base_name != "python -c pass" else ""
        print(f"{name:38s} {t:7.3f}  {t / base:6.2f}  {base_name} ({base:.3f} s){target}")
    if args.cold_demo:
        first, second = cold_demo()
        print(f"senscal demo, fresh numba cache: first run {first:.1f} s, second run {second:.1f} s "
              f"(first-run compilation {first - second:.1f} s)")


if __name__ == "__main__":
    main()
