"""Start-up cost of the command line, as ratios against a plain Python baseline (one run).

Each row runs a command in a fresh interpreter ``--repeat`` times and keeps the
best wall time (the least disturbed by other load on the machine); the rounds
interleave all commands, so load hits baseline and command alike:

- ``senscal --help`` and ``senscal fit --help`` against ``python -c "import typer"``
  (the toolkit the command line is built on: target within 2x), and for reference a
  bare Typer app printing one command's help (what Typer's rich help and its
  pydantic-based parameter conversion cost on their own);
- ``senscal fit small.csv`` against ``python -c "import numpy, scipy.linalg"`` plus
  the fit itself, timed in-process on the same file (target within 2x);
- a few other commands' ``--help`` and the old eager start (every command module
  imported first) for comparison, against ``python -c pass``.

``--registry-loop N`` also times a shell-style loop of N ``senscal registry
record`` calls into a fresh registry file (issue 16's first complaint: 40 calls
took minutes); off by default because each call opens the database.

``--cold-demo`` also times ``senscal demo`` twice with a fresh, empty numba cache
(``NUMBA_CACHE_DIR`` in a temporary folder): the first run is what a user meets on
a fresh install (every kernel the demo uses compiles), the second what they meet
afterwards.

Run: ``python benchmarks/bench_cli.py [--repeat 5] [--registry-loop 40] [--cold-demo]``.
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


def best_interleaved(cases: dict[str, list[str]], repeat: int) -> dict[str, float]:
    """Best wall time (s) of each command over ``repeat`` rounds.

    Each round runs every command once, so a load spike on a shared machine
    hits baseline and command alike instead of skewing their ratio.  A
    failing command stops the benchmark.
    """
    times: dict[str, float] = {name: float("inf") for name in cases}
    for _ in range(repeat):
        for name, argv in cases.items():
            t0 = time.perf_counter()
            r = subprocess.run(argv, capture_output=True, check=False)
            times[name] = min(times[name], time.perf_counter() - t0)
            if r.returncode != 0:
                raise SystemExit(f"{' '.join(argv)} failed ({r.returncode}): {r.stderr.decode()[-500:]}")
    return times


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


# What Typer itself costs to print one command's help: the floor for `senscal fit --help`.
TYPER_APP = """
from typing import Optional
import typer
from typing_extensions import Annotated
app = typer.Typer(rich_markup_mode="rich", add_completion=False)
@app.command()
def fit(file: str, freq: Annotated[Optional[float], typer.Option(help="Hz")] = None,
        harmonics: Annotated[int, typer.Option(help="K")] = 1, json_out: Annotated[bool, typer.Option("--json")] = False):
    pass
@app.command()
def other() -> None:
    pass
app()
"""


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


def registry_loop(n: int) -> float:
    """Wall time (s) of ``n`` successive ``senscal registry record`` calls, each a fresh process, as a shell loop."""
    with tempfile.TemporaryDirectory() as d:
        db = str(Path(d) / "reg.sqlite")
        t0 = time.perf_counter()
        for i in range(n):
            argv = [*SENSCAL, "registry", "record", f"SN-{i % 4}", "--quantity", "sensitivity", "--value",
                    f"{0.01 + i * 1e-6:.6f}", "--uncertainty", "2e-5", "--unit", "V/g", "--k", "2",
                    "--date", f"2024-01-01T00:{i // 60:02d}:{i % 60:02d}", "--create-sensor", "accelerometer",
                    "--db", db, "--create"]
            r = subprocess.run(argv, capture_output=True)
            if r.returncode != 0:
                raise SystemExit(f"senscal registry record failed: {r.stderr.decode()[-500:]}")
        return time.perf_counter() - t0


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
    ap.add_argument("--registry-loop", type=int, default=0, metavar="N",
                    help="also time N successive senscal registry record calls (e.g. 40)")
    ap.add_argument("--cold-demo", action="store_true", help="also time senscal demo on a fresh numba cache")
    args = ap.parse_args()
    r = args.repeat
    py = sys.executable
    with tempfile.TemporaryDirectory() as d:
        csv = small_csv(Path(d))
        t_fit = fit_in_process(csv, r)
        t = best_interleaved({
            "pass": [py, "-c", "pass"],
            "typer": [py, "-c", "import typer"],
            "np": [py, "-c", "import numpy, scipy.linalg"],
            "typer app: fit --help": [py, "-c", TYPER_APP, "fit", "--help"],
            "senscal --help": [*SENSCAL, "--help"],
            "senscal fit --help": [*SENSCAL, "fit", "--help"],
            "senscal fit small.csv": [*SENSCAL, "fit", str(csv)],
            "senscal registry --help": [*SENSCAL, "registry", "--help"],
            "senscal gfimu --help": [*SENSCAL, "gfimu", "--help"],
            "eager: all command modules + --help":
                [py, "-c", "from senscal.cli import load_commands, main; load_commands(); main(['--help'])"],
        }, r)
    t_pass, t_typer, t_np = t["pass"], t["typer"], t["np"]
    rows = [(name, t[name], "import typer", t_typer)
            for name in ("senscal --help", "senscal fit --help", "typer app: fit --help")]
    rows.append(("senscal fit small.csv", t["senscal fit small.csv"], "import numpy, scipy.linalg + fit",
                 t_np + t_fit))
    rows += [(name, t[name], "python -c pass", t_pass)
             for name in ("senscal registry --help", "senscal gfimu --help", "eager: all command modules + --help")]
    print(f"baselines (best of {r}): python -c pass {t_pass:.3f} s, import typer {t_typer:.3f} s, "
          f"import numpy, scipy.linalg {t_np:.3f} s, fit of small.csv in-process {t_fit * 1e3:.1f} ms")
    print(f"{'command':38s} {'best s':>7s}  {'ratio':>6s}  against")
    for name, t, base_name, base in rows:
        target = "  (target <= 2)" if base_name != "python -c pass" and not name.startswith("typer") else ""
        print(f"{name:38s} {t:7.3f}  {t / base:6.2f}  {base_name} ({base:.3f} s){target}")
    if args.registry_loop > 0:
        n = args.registry_loop
        total = registry_loop(n)
        print(f"{n} x senscal registry record (shell loop): {total:.1f} s, {total / n:.3f} s a call "
              f"({total / n / t_pass:.1f}x python -c pass)")
    if args.cold_demo:
        first, second = cold_demo()
        print(f"senscal demo, fresh numba cache: first run {first:.1f} s, second run {second:.1f} s "
              f"(first-run compilation {first - second:.1f} s)")


if __name__ == "__main__":
    main()
