"""``senscal drift-fleet`` and ``senscal simulate fleet``: drift correction of many channels on Dask."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import units
from senscal.cli.app import app, simulate_app
from senscal.cli.common import JsonOpt, StrictOpt, console, emit_warnings, fmt, print_json, progress_bar, table


def _options(*, config: Path, state: Optional[Path] = None, out: Optional[Path] = None, workers: int = 2,
             scheduler: Optional[str] = None, **_):
    from senscal.drift.fleet import FleetOptions

    return FleetOptions(config=str(config), state=None if state is None else str(state),
                        out=None if out is None else str(out), workers=workers, scheduler=scheduler)


#: ``senscal batch`` and the job layer build the fleet job's options from the command's words.
JOB_OPTIONS = {"drift-fleet": _options}


@app.command("drift-fleet")
def drift_fleet_cmd(
    dataset: Annotated[Path, typer.Argument(help="Folder of Parquet files: a time column t (s), one column per channel.")],
    config: Annotated[Path, typer.Option("--config", help="Channel groups: set-up and noise levels per group (YAML or JSON).")],
    state: Annotated[Optional[Path], typer.Option(
        "--state", help="State store folder: continued if it exists, updated after every row group.")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Folder for the corrected data (Parquet per block and row group).")] = None,
    workers: Annotated[int, typer.Option("--workers", help="Worker processes of the local Dask cluster (0: this process).")] = 2,
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", help="Address of a running Dask scheduler.")] = None,
    show: Annotated[int, typer.Option("--show", help="Channels listed in the table (largest |bias|/u first).")] = 10,
    strict: StrictOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Drift correction of a fleet: every channel of a Parquet dataset, blocks in parallel on Dask."""
    import numpy as np

    from senscal.drift.fleet import _Client, load_fleet_config, plan_blocks, run_fleet

    opts = _options(config=config, state=state, out=out, workers=workers, scheduler=scheduler)
    groups = load_fleet_config(opts.config)
    n_blocks = len(plan_blocks(dataset, groups)[0])
    with _Client(opts.workers, opts.scheduler) as client:
        with progress_bar(f"drift-fleet: {n_blocks} blocks", n_blocks, disable=json_out) as advance:
            res = run_fleet(dataset, groups, state=opts.state, out=opts.out, client=client,
                            progress=lambda row: advance())
    if json_out:
        print_json(res.to_dict())
    else:
        z = np.abs(res.bias) / np.where(res.u_bias > 0, res.u_bias, np.nan)
        order = np.argsort(-np.nan_to_num(z, nan=-1.0))[:max(show, 0)]
        console.print(table("largest biases (k=2)", ["channel", "group", "bias", "U (k=2)", "|bias|/u", "t_last [s]"],
                            [[res.channels[i], res.groups[i], fmt(res.bias[i]), fmt(2 * res.u_bias[i]),
                              f"{z[i]:.1f}", fmt(res.t_last[i])] for i in order]))
        console.print(f"{len(res.channels)} channels, {res.n_samples} samples ({res.n_missing} missing) in "
                      f"{res.n_blocks} blocks on {res.workers or 'no'} workers: {res.wall_seconds:.1f} s, "
                      f"{res.samples_per_second:.3g} samples/s"
                      + (f"; state in {res.state}" if res.state else "") + (f"; corrected data in {res.out}" if res.out else ""))
    emit_warnings(res.warnings, strict)


@simulate_app.command("fleet")
@units(fs='Hz')
def simulate_fleet_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
    channels: Annotated[int, typer.Option("--channels", help="Number of sensors.")] = 20,
    samples: Annotated[int, typer.Option("--samples", help="Samples per sensor (all segments).")] = 2000,
    fs: Annotated[str, typer.Option("--fs", help="Sample rate in Hz.")] = "1.0",
    kind: Annotated[str, typer.Option("--kind", help="known (true reading zero, random-walk bias) or covariate (temperature-linked bias).")] = "known",
    segments: Annotated[int, typer.Option("--segments", help="Consecutive datasets (seg-000, seg-001, ...: one a day, say).")] = 1,
    channels_per_file: Annotated[int, typer.Option("--channels-per-file", help="Channels per Parquet file.")] = 500,
    rows_per_group: Annotated[int, typer.Option("--rows-per-group", help="Samples per Parquet row group.")] = 3600,
    missing: Annotated[float, typer.Option("--missing", help="Fraction of samples missing (NaN).")] = 0.0,
) -> None:
    """A fleet of drifting sensors as Parquet files, its configuration (fleet.json) and truth (fleet_truth.json)."""
    from senscal.simulate import write_truth
    from senscal.simulate.fleet import simulate_fleet

    truth = simulate_fleet(out, n_channels=channels, n_samples=samples, fs=fs, kind=kind, segments=segments,
                           channels_per_file=channels_per_file, rows_per_group=rows_per_group, missing=missing,
                           seed=seed)
    q = write_truth(truth, out / "fleet_truth.json")
    console.print(f"wrote {channels} channels x {samples} samples in {', '.join(truth['segments'])}; "
                  f"configuration {out / 'fleet.json'}, truth {q}")
