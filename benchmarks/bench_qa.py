"""Cost of the QA safety checks, as ratios against the work they guard (one run).

- ``check_output`` (folder, input-collision and writability checks) against
  writing a 100k-sample CSV with ``write_recording``;
- the magnitude check added to ``fit_sine`` (one max-abs pass) against the
  sine fit of the same 8 x 100k array with the frequency estimated.

Run: ``python benchmarks/bench_qa.py``.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from senscal.io import Recording, write_recording
from senscal.io.guard import check_output, note_input, protect_inputs
from senscal.sinefit import fit_sine
from senscal.sinefit.core import _check_magnitude


def best(fn, repeat=5):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(0)
    n = 100_000
    t = np.arange(n) / 10_000.0
    y = np.sin(2 * np.pi * 123.4 * t) + 0.01 * rng.standard_normal((8, n))
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "out.csv"
        rec = Recording({"x": y[0]}, t=t)
        with protect_inputs():
            for i in range(20):  # a command with 20 inputs
                p = Path(d) / f"in{i}.csv"
                p.write_text("t,x\n0,1\n")
                note_input(p)
            write_recording(rec, out)
            t_guard = best(lambda: check_output(out), 50)
            t_write = best(lambda: write_recording(rec, out), 3)
    t_mag = best(lambda: _check_magnitude(y), 20)
    t_fit = best(lambda: fit_sine(y, t), 3)
    print(f"check_output (20 inputs)      {t_guard * 1e6:8.1f} us   write_recording 100k CSV {t_write * 1e3:7.1f} ms   "
          f"ratio {t_guard / t_write:.2e}")
    print(f"fit_sine magnitude check      {t_mag * 1e3:8.3f} ms   fit_sine 8 x 100k (f estimated) {t_fit * 1e3:7.1f} ms   "
          f"ratio {t_mag / t_fit:.2e}")


if __name__ == "__main__":
    main()
