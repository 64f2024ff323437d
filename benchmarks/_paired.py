"""The command line both paired before/after checks share: ``capture OUT [--seeds N] [--only ...]``, then
``compare BEFORE AFTER`` (``drift_paired.py``, ``primary_paired.py``)."""

from __future__ import annotations

import argparse
from typing import Callable


def paired_main(doc: str, capture: Callable, compare: Callable, *, seeds: int, only_help: str) -> None:
    """Parse the two subcommands and run ``capture(out, seeds, only)`` or ``compare(before, after)``."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture")
    c.add_argument("out")
    c.add_argument("--seeds", type=int, default=seeds)
    c.add_argument("--only", help=only_help)
    d = sub.add_parser("compare")
    d.add_argument("before")
    d.add_argument("after")
    args = ap.parse_args()
    if args.cmd == "capture":
        capture(args.out, args.seeds, args.only.split(",") if args.only else None)
    else:
        compare(args.before, args.after)


def load_pairs(a_path: str, b_path: str, what: str) -> dict:
    """The two captures' results paired and grouped by setting: ``{setting: [(before, after), ...]}``.

    Refuses captures of different lengths or orders (taken with other seeds or settings).
    """
    import json
    from collections import defaultdict

    with open(a_path) as fh:
        a_all = json.load(fh)
    with open(b_path) as fh:
        b_all = json.load(fh)
    if len(a_all) != len(b_all):
        raise SystemExit(f"different numbers of results: {len(a_all)} and {len(b_all)}; capture with the same seeds")
    by = defaultdict(list)
    for a, b in zip(a_all, b_all):
        if a["scen"] != b["scen"]:
            raise SystemExit(f"the captures do not list the same {what} in the same order")
        by[a["scen"]].append((a, b))
    return by
