"""Start-up cost of the command line, as ratios against a bare Python start (one run).

Each row runs a command in a fresh interpreter ``--repeat`` times and keeps the
best wall time: ``python -c pass`` (the floor), ``senscal --help`` and a few
``--help`` of single commands (lazy: only that command's module loads), and
the old eager start (every command module imported first) for comparison.

Run: ``python benchmarks/bench_cli.py [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time

CASES = [
    ("python -c pass", ["-c", "pass"]),
    ("senscal --help", ["-m", "senscal", "--help"]),
    ("senscal registry --help", ["-m", "senscal", "registry", "--help"]),
    ("senscal fit --help", ["-m", "senscal", "fit", "--help"]),
    ("senscal gfimu --help", ["-m", "senscal", "gfimu", "--help"]),
    ("eager: all command modules + --help",
     ["-c", "import sys; from senscal.cli import load_commands, main; load_commands(); main(['--help'])"]),
]


def best(argv: list[str], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, *argv], capture_output=True, check=False)
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    rows = [(name, best(argv, args.repeat)) for name, argv in CASES]
    floor = rows[0][1]
    print(f"{'command':40s} {'best s':>8s} {'x python':>9s}")
    for name, t in rows:
        print(f"{name:40s} {t:8.3f} {t / floor:9.1f}")


if __name__ == "__main__":
    main()
