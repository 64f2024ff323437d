"""Automatic triaxial model choice on every real recording: held-out corrected-norm error of each model.

For each three-axis recording in ``../shared/data`` (beside the repository) and ``tests/data``, runs
``senscal.triaxial.calibrate`` with the automatic choice and prints, per candidate model, the RMS of the
corrected field norm ``|H| / F - 1`` of readings held out over 5 contiguous time blocks (what ``triaxial
apply`` gives on new data; a planar model on its two corrected axes), the model chosen, and its error
relative to the best of ``full``, ``diagonal`` and ``offsets`` (the issue-26 criterion: at most 1.05).

Run: ``python benchmarks/bench_triaxial_real.py [--markdown]`` (PYTHONPATH=src).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from senscal.triaxial import calibrate

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
TESTS = ROOT / "tests" / "data"


def _cols(path, cols, skiprows=0, start=0):
    d = pd.read_csv(path, skiprows=skiprows)
    return d[list(cols)].to_numpy(float).T[:, start:]


def recordings():
    """(name, readings (3, N)) of every real three-axis recording found."""
    out = []
    if SHARED.is_dir():
        out += [
            ("shared: HMC5883L full sphere", lambda: _cols(SHARED / "mag_sunsided_full_sphere_hmc5883l.csv", "xyz")),
            ("shared: HMC5883L level turn", lambda: _cols(SHARED / "mag_sunsided_level_turn_hmc5883l.csv", "xyz")),
            # 50 Hz; the documented 60 s static start is dropped.
            ("shared: QMC5883L after 60 s", lambda: _cols(SHARED / "mag_tomisuarez2_qmc5883l_filtered.csv",
                                                          ("mx", "my", "mz"), 2, 3000)),
            ("shared: CK-Explorer magnetometer", lambda: _cols(SHARED / "magacc_ckexplorer_tumble.csv",
                                                               ("mx", "my", "mz"))),
            ("shared: CK-Explorer accelerometer", lambda: _cols(SHARED / "magacc_ckexplorer_tumble.csv",
                                                                ("ax", "ay", "az"))),
        ]
    out += [
        ("tests: HMC5883L full sphere (1 in 4)", lambda: _cols(TESTS / "mag_sunsided_full_sphere_hmc5883l_dec4.csv", "xyz")),
        ("tests: HMC5883L level turn", lambda: _cols(TESTS / "mag_sunsided_level_turn_hmc5883l.csv", "xyz")),
        ("tests: QMC5883L after 60 s (1 in 5)", lambda: _cols(TESTS / "mag_tomisuarez2_qmc5883l_dec5.csv",
                                                             ("mx", "my", "mz"), 2, 600)),
        ("tests: CK-Explorer magnetometer (1 in 6)", lambda: _cols(TESTS / "magacc_ckexplorer_tumble_dec6.csv",
                                                                   ("mx", "my", "mz"))),
        ("tests: CK-Explorer accelerometer (1 in 6)", lambda: _cols(TESTS / "magacc_ckexplorer_tumble_dec6.csv",
                                                                    ("ax", "ay", "az"))),
    ]
    return out


def row(name, h):
    t0 = time.perf_counter()
    res = calibrate(h)
    ev = {e["model"]: e["held_out_percent"] for e in res.model_evidence}
    best3 = min(v for m, v in ev.items() if m in ("full", "diagonal", "offsets") and v is not None)
    auto = ev[res.model]
    return {"recording": name, "n": h.shape[1], **{m: ev.get(m) for m in ("full", "diagonal", "offsets", "planar")},
            "auto": res.model, "auto %": auto, "auto / best": auto / best3, "s": time.perf_counter() - t0,
            "warnings": ",".join(w.split(":")[0] for w in res.warnings)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args(argv)
    rows = [row(n, f()) for n, f in recordings()]
    head = ["recording", "n", "full", "diagonal", "offsets", "planar", "auto", "auto %", "auto / best", "s"]

    def fmt(v):
        return "-" if v is None else (f"{v:.3f}" if isinstance(v, float) else str(v))

    lines = [[fmt(r[k]) for k in head] for r in rows]
    if args.markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for ln in lines:
            print("| " + " | ".join(ln) + " |")
    else:
        w = [max(len(h), *(len(ln[i]) for ln in lines)) for i, h in enumerate(head)]
        print("  ".join(h.ljust(x) for h, x in zip(head, w)))
        for ln in lines:
            print("  ".join(c.ljust(x) for c, x in zip(ln, w)))
    for r in rows:
        if r["warnings"]:
            print(f"# {r['recording']}: warnings {r['warnings']}", file=sys.stderr)
    bad = [r["recording"] for r in rows if r["auto / best"] > 1.05]
    print(f"{len(rows)} recordings; automatic choice more than 5 % worse than the best on {len(bad)}"
          + (f": {', '.join(bad)}" if bad else ""), file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
