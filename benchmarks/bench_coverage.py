"""Coverage of every reported uncertainty, white and departed cases, in one run.

Runs every scenario in ``senscal.validation`` (one module per job) with the
full number of Monte-Carlo seeds and prints, per job, case and quantity: the
fraction of seeds whose k=2 interval covers the simulated truth, its 99.9 %
Wilson interval, the spread of the z-scores ``(estimate - truth) / u`` (1 when
u is right), the fraction of seeds that raised the case's named warning, and
whether the row meets the rule (covers 95 +/- 2 %, or the departure is named).

Run: ``python benchmarks/bench_coverage.py [JOB ...] [--seeds N] [--markdown]``.
The tests run the same scenarios with fewer seeds (``senscal.validation.mc_seeds``).

``--sweep N`` runs the random departure sweep instead (:mod:`senscal.validation.sweep`):
N random cases per job (JOB names the sweep's jobs), then prints the verdict per
departure class (silent misses against the 5 % an honest interval allows, one-sided
binomial test at 1e-3) and the worst silent misses (job, departures, strengths,
quantity, |err|/U, warnings).  Exit 1 when a class fails.
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
    ap.add_argument("--sweep", type=int, default=None, metavar="N",
                    help="random departure sweep: N random cases per job (senscal.validation.sweep)")
    ap.add_argument("--only", default=None, metavar="TEXT",
                    help="run only the scenarios whose name contains TEXT (a job's exact scenario name: only that one)")
    ap.add_argument("--seed0", type=int, default=0, help="first case of the sweep")
    ap.add_argument("--show", type=int, default=25, help="silent misses listed by the sweep (worst first)")
    ap.add_argument("--summary", action="store_true",
                    help="sweep: one row per job and departure class (quantities pooled) instead of per quantity")
    args = ap.parse_args(argv)
    if args.sweep is not None:
        return _sweep(args)
    allsc = scenarios()
    jobs = args.jobs or sorted(allsc)
    rows = []
    for job in jobs:
        if job not in allsc:
            print(f"bench_coverage: unknown job {job!r}; known: {', '.join(sorted(allsc))}", file=sys.stderr)
            return 2
        exact = args.only in allsc[job] if args.only else False
        for name, run in allsc[job].items():
            if args.only and (name != args.only if exact else args.only not in name):
                continue
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


def _fmt_strengths(d) -> str:
    return ", ".join(f"{k}={v:.3g}" for k, v in d.items()) or "none"


def _print(head, lines, markdown: bool) -> None:
    if markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for ln in lines:
            print("| " + " | ".join(ln) + " |")
        return
    widths = [max(len(h), *(len(ln[i]) for ln in lines)) if lines else len(h) for i, h in enumerate(head)]
    print("  ".join(h.ljust(w) for h, w in zip(head, widths)))
    for ln in lines:
        print("  ".join(c.ljust(w) for c, w in zip(ln, widths)))


def _sweep(args) -> int:
    from senscal.validation.sweep import JOBS, case_classes, run_sweep, sweep_table

    jobs = args.jobs or list(JOBS)
    unknown = [j for j in jobs if j not in JOBS]
    if unknown:
        print(f"bench_coverage: unknown sweep job {unknown[0]!r}; known: {', '.join(JOBS)}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    cases = []
    for job in jobs:
        t1 = time.perf_counter()
        cases.extend(run_sweep(args.sweep, jobs=[job], seed0=args.seed0))
        print(f"# sweep {job}: {args.sweep} cases in {time.perf_counter() - t1:.1f} s", file=sys.stderr)
    rows = sweep_table(cases)
    n_cases = len({(c.job, c.seed) for c in cases})
    silent = [c for c in cases if c.silent_miss]
    bad = [r for r in rows if not r.ok]
    print(f"sweep: {n_cases} random cases ({args.sweep} per job, seeds {args.seed0}..{args.seed0 + args.sweep - 1}), "
          f"{len(cases)} quantities, {len(silent)} silent misses ({100 * len(silent) / max(len(cases), 1):.1f} %; "
          f"an honest k=2 interval allows 5 %), {len(bad)} of {len(rows)} classes fail")
    if args.summary:
        # quantities pooled per class: cases, silent misses over all quantities, the classes' failing quantities
        groups: dict = {}
        n_cases: dict = {}
        for r in rows:
            groups.setdefault((r.job, r.departure), []).append(r)
        for job_seed in {(c.job, c.seed): c for c in cases}.values():
            for d in case_classes(job_seed.strengths):
                n_cases[(job_seed.job, d)] = n_cases.get((job_seed.job, d), 0) + 1
        head = ["job", "departure", "cases", "quantities", "covered %", "named %", "silent %", "failing quantities"]
        lines = []
        for (job, dep), rs in groups.items():
            nq = sum(r.n for r in rs)
            lines.append([job, dep, str(n_cases.get((job, dep), 0)), str(nq),
                          f"{100 * sum(r.covered * r.n for r in rs) / nq:.0f}",
                          f"{100 * sum(r.named * r.n for r in rs) / nq:.0f}",
                          f"{100 * sum(r.silent for r in rs) / nq:.1f}",
                          ", ".join(r.quantity for r in rs if not r.ok) or "-"])
    else:
        head = ["job", "departure", "quantity", "n", "covered %", "named %", "silent", "P(>=silent | 5 %)",
                "worst |err|/U", "ok"]
        lines = [[r.job, r.departure, r.quantity, str(r.n), f"{100 * r.covered:.0f}", f"{100 * r.named:.0f}",
                  str(r.silent), f"{r.p_value:.2g}", f"{r.worst:.2f}" if r.silent else "", "yes" if r.ok else "NO"]
                 for r in rows]
    print()
    _print(head, lines, args.markdown)
    if silent:
        print()
        print(f"worst silent misses ({min(args.show, len(silent))} of {len(silent)}):")
        worst = sorted(silent, key=lambda c: -c.ratio)[:args.show]
        _print(["job", "case", "departures (strengths)", "quantity", "|err|/U", "warnings"],
               [[c.job, str(c.seed), _fmt_strengths(c.strengths), c.quantity, f"{c.ratio:.2f}",
                 ",".join(c.warnings) or "-"] for c in worst], args.markdown)
    print(f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
