"""``senscal demo``: every job on simulated truth, one report."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer
from typing_extensions import Annotated

from senscal.cli.app import app
from senscal.cli.common import console, progress_bar, table


@app.command("demo")
def demo_cmd(
    out: Annotated[Path, typer.Option("--out", help="Folder for the outputs and index.html.")] = Path("senscal-demo"),
    seed: Annotated[int, typer.Option("--seed", help="Random seed of the simulations.")] = 1,
    only: Annotated[Optional[List[str]], typer.Option("--only", help="Run only this job (repeatable), e.g. sinefit.")] = None,
) -> None:
    """Run every job on simulated data with known truth and write a report (index.html)."""
    from senscal.demo import discover, run_demo
    from senscal.errors import InputError

    keys = [m.__name__.rsplit(".", 1)[1][len("job_"):] for m in discover()]
    unknown = [k for k in (only or []) if k not in keys]
    if unknown:
        raise InputError(f"no demo job '{unknown[0]}'; jobs are: {', '.join(keys)}")
    total = len(only) if only else len(keys)

    def done(sec):
        advance()
        console.rule(sec.title)
        console.print(sec.summary)
        if sec.rows:
            console.print(table("truth vs estimate (u: standard uncertainty, k=1)",
                                ["quantity", "truth", "estimate", "u", "unit"],
                                [[r["quantity"], r.get("truth"), r.get("estimate"), r.get("uncertainty"), r.get("unit", "")]
                                 for r in sec.rows]))
        for t in sec.tables:
            console.print(table(t["title"], t["columns"], t["rows"]))
        for f in sec.files:
            console.print(f"  wrote {out / f}")

    with progress_bar("demo jobs", total) as advance:
        _, index = run_demo(out, seed=seed, only=only, on_done=done)
    console.print(f"\nReport: {index.resolve()}  (open it in a browser)")
