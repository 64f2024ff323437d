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
