"""Coverage of every reported uncertainty, white and departed cases, in one run.

Runs every scenario in ``senscal.validation`` (one module per job) with the
full number of Monte-Carlo seeds and prints, per job, case and quantity: the
fraction of seeds whose k=2 interval covers the simulated truth, its 99.9 %
Wilson interval, the spread of the z-scores ``(estimate - truth) / u`` (1 when
u is right), the fraction of seeds that raised the case's named warning, and
whether the row meets the rule (covers 95 +/- 2 %, or the departure is named).

Run: ``python benchmarks/bench_coverage.py [JOB ...] [--seeds N] [--markdown]``.
The tests run the same scenarios with fewer seeds (``senscal.validation.mc_seeds``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("SENSCAL_MC", "full")

from senscal.validation import mc_seeds, scenarios  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("jobs", nargs="*", help="modules of senscal.validation to run (default: all)")
    ap.add_argument("--seeds", type=int, default=None, help="override each scenario's full seed count")
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = ap.parse_args(argv)
    allsc = scenarios()
    jobs = args.jobs or sorted(allsc)
    rows = []
    for job in jobs:
        if job not in allsc:
            print(f"bench_coverage: unknown job {job!r}; known: {', '.join(sorted(allsc))}", file=sys.stderr)
            return 2
        for name, run in allsc[job].items():
            t0 = time.perf_counter()
            full = getattr(run, "full_seeds", 400)
            n = args.seeds if args.seeds else mc_seeds(full)
            out = run(n, 0)
            dt = time.perf_counter() - t0
            print(f"# {job}/{name}: {n} seeds in {dt:.1f} s", file=sys.stderr)
            rows.extend(out)
    head = ["job", "case", "quantity", "n", "coverage %", "99.9% CI", "z spread", "warned %", "expect", "ok"]
    lines = []
    for r in rows:
        lo, hi = r.interval
        warned = "" if r.warned != r.warned else f"{100 * r.warned:.0f}"
        lines.append([r.job, r.case, r.quantity, str(r.n), f"{100 * r.coverage:.1f}",
                      f"{100 * lo:.1f}-{100 * hi:.1f}", f"{r.z_spread:.2f}", warned, r.expect,
                      "yes" if r.ok else "NO"])
    if args.markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for ln in lines:
            print("| " + " | ".join(ln) + " |")
    else:
        widths = [max(len(h), *(len(ln[i]) for ln in lines)) if lines else len(h) for i, h in enumerate(head)]
        print("  ".join(h.ljust(w) for h, w in zip(head, widths)))
        for ln in lines:
            print("  ".join(c.ljust(w) for c, w in zip(ln, widths)))
    bad = sum(not r.ok for r in rows)
    print(f"{len(rows)} rows, {bad} break the rule", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
