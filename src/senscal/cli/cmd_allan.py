"""``senscal allan``: Allan deviation of one channel with confidence intervals and noise levels."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import numpy as np
import typer
from typing_extensions import Annotated

from senscal.cli._quantities import ListOf, units
from senscal.cli.app import app
from senscal.cli.common import (JsonOpt, NamesOpt, SkipRowsOpt, StartOpt, StopOpt, StrictOpt, TimeColumnOpt, TimeUnitOpt,
                                console, emit_warnings, load, parse_floats, print_json, table)
from senscal.diagnostics import named
from senscal.errors import InputError

JITTER_LIMIT = 0.05  # relative spread of the sample intervals above which the time base is called irregular


def allan_doc(file: Path, *, channel: str, fs: float | None, taus: str | None, modified: bool, confidence: float,
              time_column: str, names: str | None, time_unit: str | None = None, skip_rows: int | None = None,
              start: float | None = None, stop: float | None = None):
    """Read the channel and return (JSON document, AllanResult, NoiseLevels).

    The sample rate is ``--fs``, else the recording's (:func:`senscal.io.recording.sample_rate_of`:
    the mean rate over the record when the stamps are irregular, as every job derives it).
    """
    from senscal.drift.allan import allan_deviation, identify_noise
    from senscal.io.plausibility import merge_time_warnings

    if not 0 < confidence < 1:
        raise InputError(f"--confidence must lie between 0 and 1, got {confidence:g}")
    if fs is not None and not (math.isfinite(fs) and fs > 0):
        raise InputError(f"--fs must be a positive number, got {fs:g}")
    rec = load(file, time_column=time_column, fs=fs, names=names, channels=[channel], time_unit=time_unit,
               skip_rows=skip_rows, start=start, stop=stop, job="allan")
    y = rec[channel]
    warnings: list[str] = []
    if fs is None:
        fs = rec.sample_rate
        if rec.t is not None and not rec.is_uniform:
            dt = np.diff(rec.t)
            spread = float(np.max(np.abs(dt * fs - 1.0)))
            if spread > JITTER_LIMIT:
                step = float(np.median(dt))
                # Most intervals far below the mean: buffered samples stamped as a host read them (bursts);
                # intervals near the median with a few long ones: samples missing (gaps).
                if step < 0.5 / fs:
                    how = (f"the stamps come in bursts (median interval {step:.3g} s, mean {1.0 / fs:.3g} s), as a "
                           "host stamps buffered samples when it reads them, so they do not say when each was taken")
                elif float(dt.max()) > 1.8 * step:  # one missing sample doubles an interval
                    how = (f"intervals reach {float(dt.max()) / step:.3g}x the median {step:.3g} s, as where samples "
                           "are missing; cut the record at the gaps with --start/--stop")
                else:
                    how = f"the sample intervals jitter by up to {100 * spread:.0f}% of their mean {1.0 / fs:.3g} s"
                warnings.append(named(
                    "allan-irregular-sampling",
                    f"{how}; the Allan deviation treats the samples as equally spaced at the mean rate {fs:.6g} Hz "
                    f"({dt.size} intervals over {rec.duration:.6g} s), right when the sensor sampled on its own "
                    "clock and no sample was lost; give --fs if its rate is known"))
    res = allan_deviation(y, fs, None if taus is None else parse_floats(taus, "--taus"),
                          kind="modified" if modified else "overlapping", confidence=confidence)
    lev = identify_noise(res)
    warnings = list(merge_time_warnings(warnings + list(res.warnings), rec.warnings))
    unit = rec.unit(channel) or ""
    doc = {
        "file": str(file), "channel": channel, "unit": unit, "fs_hz": fs, "n_samples": res.n_samples,
        "kind": res.kind, "confidence": res.confidence,
        "rows": [{"tau_s": float(t), "dev": float(d), "lower": float(lo), "upper": float(hi), "n_clusters": int(n),
                  "edf": float(e), "noise": nz}
                 for t, d, lo, hi, n, e, nz in zip(res.taus, res.dev, res.lower, res.upper, res.n_clusters, res.edf,
                                                   res.noise)],
        "noise_levels": {"N": lev.N, "u_N": lev.u_N, "B": lev.B, "u_B": lev.u_B, "K": lev.K, "u_K": lev.u_K,
                         "tau_min_s": lev.tau_min},
        "warnings": warnings,
    }
    return doc, res, lev


def plot_allan(res, lev, path: Path, *, channel: str, unit: str) -> Path:
    """Log-log deviation with its confidence band and the N, B, K guide lines."""
    from senscal.report.plots import new_figure, save_figure

    fig, ax = new_figure(1, 1, width=7.0, height=5.0)
    t = res.taus
    ax.fill_between(t, res.lower, res.upper, color="C0", alpha=0.25, lw=0,
                    label=f"{100 * res.confidence:.1f}% confidence interval")
    ax.loglog(t, res.dev, "o-", color="C0", ms=3, lw=1.0, label=f"{res.kind} Allan deviation")
    if lev.N is not None:
        ax.loglog(t, lev.N / np.sqrt(t), "--", color="C1", lw=1.0, label=f"white: N = {lev.N:.3g} (slope -1/2)")
    ax.axhline(lev.B * 0.664, color="C2", ls=":", lw=1.0, label=f"bias instability: B = {lev.B:.3g} (0.664 B)")
    if lev.K is not None:
        ax.loglog(t, lev.K * np.sqrt(t / 3), "-.", color="C3", lw=1.0,
                  label=f"rate random walk: K = {lev.K:.3g} (slope +1/2)")
    lo = np.nanmin(res.lower[np.isfinite(res.lower)]) if np.isfinite(res.lower).any() else np.nanmin(res.dev)
    hi = np.nanmax(res.upper[np.isfinite(res.upper)]) if np.isfinite(res.upper).any() else np.nanmax(res.dev)
    ax.set_ylim(lo / 2, hi * 2)
    ax.set_xlabel("cluster time tau (s)")
    ax.set_ylabel(f"Allan deviation of {channel}" + (f" ({unit})" if unit else ""))
    ax.grid(True, which="both", alpha=0.3)
    # Plain tick labels: save_figure turns mathtext off (user strings), which would print the log axes' TeX.
    from matplotlib.ticker import FuncFormatter, NullFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(plain)
        axis.set_minor_formatter(NullFormatter())
    ax.legend(fontsize=8, loc="lower left")
    return save_figure(fig, path)


def table_csv(doc: dict) -> str:
    lines = ["tau_s,dev,lower,upper,n_clusters,edf,noise"]
    for r in doc["rows"]:
        lines.append(f"{r['tau_s']!r},{r['dev']!r},{r['lower']!r},{r['upper']!r},{r['n_clusters']},{r['edf']!r},"
                     f"{r['noise']}")
    return "\n".join(lines) + "\n"


@app.command("allan")
@units(fs='Hz', taus=ListOf('s'))
def allan_cmd(
    file: Annotated[Path, typer.Argument(help="Recording file (CSV, Parquet, HDF5, TDMS, NPZ) of a sensor at rest.")],
    channel: Annotated[str, typer.Option("--channel", "-c", help="Channel to analyse.")],
    fs: Annotated[Optional[str], typer.Option(
        "--fs", help="Sample rate in Hz (default: the time column's mean rate over the record, the rule of "
                     "every command).")] = None,
    taus: Annotated[Optional[str], typer.Option("--taus", help="Cluster times in s, comma separated "
                                                "(default: octaves while 3 clusters fit).")] = None,
    modified: Annotated[bool, typer.Option(
        "--modified", help="Modified Allan deviation instead of the overlapping one.")] = False,
    confidence: Annotated[float, typer.Option("--confidence", help="Two-sided level of the intervals.")] = 0.683,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Log-log plot (.png, .svg, .pdf).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="CSV table of tau, deviation and interval.")] = None,
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    names: NamesOpt = None,
    time_unit: TimeUnitOpt = None,
    skip_rows: SkipRowsOpt = None,
    start: StartOpt = None,
    stop: StopOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Allan deviation with confidence intervals; white noise N, bias instability B, rate random walk K."""
    from senscal.io import check_output
    from senscal.io.guard import write_text

    if out is not None:
        out = check_output(out, suffixes=(".csv",), what="table")
    doc, res, lev = allan_doc(file, channel=channel, fs=fs, taus=taus, modified=modified, confidence=confidence,
                              time_column=time_column, names=names, time_unit=time_unit, skip_rows=skip_rows,
                              start=start, stop=stop)
    if out is not None:
        write_text(out, table_csv(doc), what="table")
    if plot is not None:
        plot_allan(res, lev, plot, channel=channel, unit=doc["unit"])
    if json_out:
        print_json(doc)
        emit_warnings(doc["warnings"], strict)
        return
    lvl = f"{100 * res.confidence:.1f}%"
    console.print(table(f"{res.kind.capitalize()} Allan deviation of {channel} in {file} ({doc['fs_hz']:g} Hz; "
                        f"{lvl} interval)", ["tau (s)", "deviation", "lower", "upper", "clusters", "edf"],
                        [[r["tau_s"], r["dev"], r["lower"], r["upper"], r["n_clusters"], f"{r['edf']:.3g}"]
                         for r in doc["rows"]]))
    u = doc["unit"] or "unit"
    nl = doc["noise_levels"]
    console.print(table("Noise levels (U = expanded uncertainty, k=2)", ["term", "value", "U", "unit"], [
        ["N white (tau = 1 s)", nl["N"], None if nl["u_N"] is None else 2 * nl["u_N"], f"{u}*sqrt(s)"],
        ["B bias instability", nl["B"], 2 * nl["u_B"], u],
        ["K rate random walk (tau = 3 s)", nl["K"], None if nl["u_K"] is None else 2 * nl["u_K"], f"{u}/sqrt(s)"],
    ]))
    console.print(f"minimum of the curve at tau = {nl['tau_min_s']:g} s")
    for p in (out, plot):
        if p is not None:
            console.print(f"wrote {p}")
    emit_warnings(doc["warnings"], strict)
