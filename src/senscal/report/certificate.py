"""Calibration certificates in HTML for the vibration jobs.

One self-contained page (plots inlined as SVG, no scripts, no network):
certificate id, item identification, date, method, conditions, results with
expanded uncertainties (k=2), the uncertainty budget per point, plots, and the
statement that the results relate only to the item calibrated.

References
----------
.. [1] ISO/IEC 17025:2017, 7.8 (reporting of results; calibration
   certificates).
.. [2] JCGM 100:2008 (GUM), 7.2 (reporting expanded uncertainty).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import jinja2
import numpy as np

from senscal._result import to_jsonable
from senscal.report.plots import new_figure, svg_inline

__all__ = ["write_certificate", "certificate_html", "response_figure", "linearity_figure", "velocity_figure"]

_TEMPLATE = jinja2.Template(
    """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Calibration certificate {{ cert_id }}</title>
<style>
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;max-width:960px;margin:2em auto;padding:0 1em;color:#222}
h1{margin-bottom:.1em}.sub{color:#555;margin-top:0}
table{border-collapse:collapse;margin:.6em 0 1.2em}td,th{border:1px solid #bbb;padding:.25em .6em;text-align:right}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}
table.kv td{text-align:left}table.kv td:first-child{font-weight:600;background:#fafafa}
.plot svg{max-width:100%;height:auto}
.note{border-top:1px solid #ccc;margin-top:2em;padding-top:.6em;font-size:.92em;color:#333}
</style></head><body>
<h1>Calibration certificate</h1>
<p class="sub">{{ title }} &middot; certificate {{ cert_id }}</p>
<table class="kv">
<tr><td>Certificate id</td><td>{{ cert_id }}</td></tr>
<tr><td>Item calibrated</td><td>{{ sensor_id }}</td></tr>
<tr><td>Model</td><td>{{ model }}</td></tr>
<tr><td>Date of issue</td><td>{{ date }}</td></tr>
<tr><td>Method</td><td>{{ method }}</td></tr>
<tr><td>Software</td><td>senscal {{ version }}</td></tr>
</table>
<h2>Conditions</h2>
<table class="kv">{% for k, v in conditions %}<tr><td>{{ k }}</td><td>{{ v }}</td></tr>{% endfor %}</table>
<h2>Results</h2>
{% for s in summary %}<p><b>{{ s[0] }}</b>: {{ s[1] }}</p>{% endfor %}
<table><tr>{% for c in columns %}<th>{{ c }}</th>{% endfor %}</tr>
{% for row in rows %}<tr>{% for v in row %}<td>{{ v }}</td>{% endfor %}</tr>{% endfor %}</table>
<p>U is the expanded uncertainty with coverage factor k = 2 (about 95 % coverage for a normal
distribution), evaluated following the GUM (JCGM 100:2008) from the standard uncertainties below;
where the effective degrees of freedom are few, k is Student's t for the same 95.45 % (shown in the budget).</p>
{% if warnings %}<h2>Warnings</h2>
<p>The data depart from the method's model as follows; the uncertainties above do not cover these departures.</p>
<ul>{% for w in warnings %}<li>{{ w }}</li>{% endfor %}</ul>{% endif %}
{% if budgets %}<h2>Uncertainty budget (standard uncertainties, k = 1)</h2>{% endif %}
{% for bcols, brows in budgets %}<table><tr>{% for c in bcols %}<th>{{ c }}</th>{% endfor %}</tr>
{% for row in brows %}<tr>{% for v in row %}<td>{{ v }}</td>{% endfor %}</tr>{% endfor %}</table>{% endfor %}
{% for p in plots %}<div class="plot">{{ p | safe }}</div>{% endfor %}
<div class="note">
<p>The results relate only to the item calibrated, under the conditions stated above.
This certificate shall not be reproduced except in full.</p>
<p>Records: {{ files }}</p>
</div>
</body></html>
""",
    autoescape=True,
)


def _g(v: Any, digits: int = 6) -> str:
    if v is None:
        return "-"
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return "-" if not math.isfinite(f) else f"{f:.{digits}g}"


def _u(v: Any) -> str:
    """Uncertainties with 2 significant digits (GUM 7.2.6)."""
    return _g(v, 2)


def response_figure(resp):
    """Bode plot: (normalised) sensitivity and phase delay vs log frequency with k=2 bars."""
    pts = resp.points
    f = np.array([p.frequency for p in pts])
    norm = all(p.normalized_sensitivity is not None for p in pts)
    mag = np.array([p.normalized_sensitivity if norm else p.sensitivity for p in pts], dtype=float)
    umag = np.array([p.u_normalized_sensitivity if norm else p.u_sensitivity for p in pts], dtype=float)
    has_ph = all(p.phase_delay is not None for p in pts)
    fig, ax = new_figure(2 if has_ph else 1, 1, height=5.5 if has_ph else 3.2, sharex=True, squeeze=False)
    ax = ax[:, 0]
    ax[0].errorbar(f, mag, yerr=2 * umag, fmt="o-", capsize=3)
    ax[0].set_xscale("log")
    ax[0].set_ylabel("S_i / S_0" if norm else f"sensitivity ({resp.unit})")
    ax[0].grid(True, which="both", alpha=0.3)
    ax[0].set_title("Frequency response (bars: U, k=2)")
    if has_ph:
        ph = np.degrees([p.phase_delay for p in pts])
        uph = np.degrees([p.u_phase_delay for p in pts])
        ax[1].errorbar(f, ph, yerr=2 * uph, fmt="s-", color="C1", capsize=3)
        ax[1].set_ylabel("phase delay (deg)")
        ax[1].grid(True, which="both", alpha=0.3)
    ax[-1].set_xlabel("frequency (Hz)")
    return fig


def linearity_figure(lin, unit: str = ""):
    """Output amplitude vs input with the best straight line, and the deviations."""
    x = np.array([p.input_amplitude for p in lin.points])
    y = np.array([p.output_amplitude for p in lin.points])
    u = np.array([p.u_output_amplitude for p in lin.points])
    d = np.array([p.deviation_percent for p in lin.points])
    fig, ax = new_figure(2, 1, height=5.5, sharex=True)
    xx = np.linspace(0, x.max() * 1.05, 50)
    ax[0].plot(xx, lin.slope * xx + lin.intercept, "-", lw=1, label="best straight line")
    ax[0].errorbar(x, y, yerr=2 * u, fmt="o", capsize=3, label="fitted output amplitude")
    ax[0].set_ylabel(f"output amplitude {unit}".strip())
    ax[0].legend(loc="upper left")
    ax[0].grid(True, alpha=0.3)
    ax[1].errorbar(x, d, yerr=200 * u / lin.full_scale_output, fmt="o-", capsize=3, color="C1")
    ax[1].axhline(0, color="k", lw=0.8)
    ax[1].set_ylabel("deviation (% of full scale)")
    ax[1].set_xlabel("input amplitude (m/s^2)")
    ax[1].grid(True, alpha=0.3)
    return fig


def velocity_figure(cal):
    """Sensitivity and phase of a velocity sensor vs frequency, with the mean and its U."""
    f = np.array([p.frequency for p in cal.points])
    s = np.array([p.sensitivity for p in cal.points])
    us = np.array([p.u_sensitivity for p in cal.points])
    ph = np.degrees([p.phase for p in cal.points])
    uph = np.degrees([p.u_phase for p in cal.points])
    fig, ax = new_figure(2, 1, height=5.5, sharex=True)
    ax[0].errorbar(f, s, yerr=2 * us, fmt="o", capsize=3, label="points (U, k=2)")
    ax[0].axhline(cal.sensitivity, color="C2", lw=1, label="mean")
    ax[0].axhspan(cal.sensitivity - 2 * cal.u_sensitivity, cal.sensitivity + 2 * cal.u_sensitivity,
                  color="C2", alpha=0.15, label="mean +/- U")
    ax[0].set_ylabel(f"sensitivity ({cal.unit})")
    ax[0].legend(loc="best")
    ax[0].grid(True, alpha=0.3)
    ax[1].errorbar(f, ph, yerr=2 * uph, fmt="s", capsize=3, color="C1")
    ax[1].set_ylabel("phase vs velocity (deg)")
    ax[1].set_xlabel("frequency (Hz)")
    ax[1].grid(True, alpha=0.3)
    return fig


def _budget_table(budgets: Sequence[Any], labels: Sequence[str]) -> tuple[list[str], list[list[str]]]:
    budgets = [b for b in budgets if b is not None]
    if not budgets:
        return [], []
    sources = [f"{c.source} [{c.kind}]" for c in budgets[0].components]
    # k per row: 2 for many degrees of freedom, Student's t where they are few
    cols = ["point", "quantity", "value"] + sources + ["u_c", "k", "U", "unit"]
    rows = [[lab, b.quantity, _g(b.value)] + [_u(c.standard_uncertainty) for c in b.components]
            + [_u(b.combined), _g(b.coverage_factor, 3), _u(b.expanded), b.unit] for lab, b in zip(labels, budgets)]
    return cols, rows


def _in_degrees(b):
    from senscal.vibration.budget import make_budget

    return make_budget(b.quantity, math.degrees(b.value), "deg",
                       [(c.source, c.kind, math.degrees(c.standard_uncertainty), c.dof) for c in b.components],
                       b.coverage_factor)


def _tables(kind: str, result: Any, unit: str):
    if kind == "response":
        pts = result.points
        norm = all(p.normalized_sensitivity is not None for p in pts)
        has_ph = all(p.phase_delay is not None for p in pts)
        cols = ["frequency (Hz)", f"sensitivity ({unit})", "U"]
        cols += ["S_i / S_0", "U"] if norm else []
        cols += ["phase delay (deg)", "U (deg)"] if has_ph else []
        rows = []
        for p in pts:
            r = [_g(p.frequency), _g(p.sensitivity), _u(2 * p.u_sensitivity)]
            if norm:
                r += [_g(p.normalized_sensitivity), _u(2 * p.u_normalized_sensitivity)]
            if has_ph:
                r += [_g(math.degrees(p.phase_delay), 5), _u(2 * math.degrees(p.u_phase_delay))]
            rows.append(r)
        labels = [f"{p.frequency:g} Hz" for p in pts]
        bud = [p.normalized_budget if norm else p.sensitivity_budget for p in pts]
        budgets = [_budget_table(bud, labels)]
        if has_ph:
            budgets.append(_budget_table([_in_degrees(p.phase_delay_budget) for p in pts], labels))
        summary = ([("Input phase phi_0", result.phase_reference)] if getattr(result, "phase_reference", "")
                   and has_ph else [])
        figs = [response_figure(result)]
    elif kind == "velocity":
        cols = ["frequency (Hz)", f"sensitivity ({unit})", "U", "phase vs velocity (deg)", "U (deg)"]
        rows = [[_g(p.frequency), _g(p.sensitivity), _u(2 * p.u_sensitivity), _g(math.degrees(p.phase), 4),
                 _u(2 * math.degrees(p.u_phase))] for p in result.points]
        budgets = [_budget_table([p.budget for p in result.points], [f"{p.frequency:g} Hz" for p in result.points]),
                   _budget_table([result.budget], ["mean"])]
        summary = [("Mean sensitivity", f"{_g(result.sensitivity)} {unit}, U = {_u(result.budget.expanded)} {unit} "
                    f"(k={_g(result.budget.coverage_factor, 3)}); standard deviation over {len(result.points)} points "
                    f"{_u(result.sensitivity_std)} {unit}")]
        figs = [velocity_figure(result)]
    elif kind == "linearity":
        cols = ["input amplitude (m/s^2)", "output amplitude", "U", "deviation", "deviation (% FS)"]
        rows = [[_g(p.input_amplitude), _g(p.output_amplitude), _u(2 * p.u_output_amplitude), _g(p.deviation, 3),
                 _g(p.deviation_percent, 3)] for p in result.points]
        budgets = []
        k = getattr(result, "coverage_factor", 2.0)
        if getattr(result, "linearity_resolved", None) is False:
            lin_text = (f"below {_g(result.linearity_bound_percent, 2)} % of full-scale output "
                        f"({_g(result.full_scale_output)}): not resolved, the largest deviation "
                        f"{_g(result.linearity_percent, 2)} % is within the noise")
        else:
            lin_text = (f"{_g(result.linearity_percent, 3)} % of full-scale output ({_g(result.full_scale_output)}), "
                        f"U = {_u(2 * result.u_linearity_percent)} % (k=2, Monte Carlo, JCGM 101)")
        summary = [("Amplitude linearity", lin_text),
                   ("Sensitivity (slope)", f"{_g(result.slope)} {unit}, U = {_u(k * result.u_slope)} (k={_g(k, 3)})"),
                   ("Intercept", f"{_g(result.intercept)}, U = {_u(k * result.u_intercept)} (k={_g(k, 3)})")]
        figs = [linearity_figure(result)]
    else:
        from senscal.errors import InputError

        raise InputError(f"unknown certificate kind {kind!r}; use response, velocity or linearity")
    return cols, rows, budgets, summary, figs


_TITLES = {"response": "Accelerometer frequency response", "velocity": "Velocity-sensor sensitivity",
           "linearity": "Accelerometer amplitude linearity"}


def certificate_html(kind: str, result: Any, *, sensor_id: str = "not stated", model: str = "not stated",
                     method: str = "", conditions: Mapping[str, Any] | None = None, unit: str = "",
                     files: Sequence[str] = (), date: _dt.datetime | None = None,
                     warnings: Sequence[str] | None = None) -> str:
    """Render a certificate as one self-contained HTML string.

    Parameters
    ----------
    kind : str
        ``"response"`` (FrequencyResponse), ``"velocity"`` (VelocityCalibration)
        or ``"linearity"`` (AmplitudeLinearity).
    result : object
        The result of that job.
    sensor_id, model : str
        Identification of the item calibrated.
    method : str
        Method statement.
    conditions : mapping
        Conditions of the calibration (shown as given).
    unit : str
        Sensitivity unit.
    files : sequence of str
        Records used.
    date : datetime, optional
        Date of issue (default: now, UTC).
    warnings : sequence of str, optional
        Named warnings to print on the certificate (default: the result's
        own ``warnings``).
    """
    from senscal import __version__

    date = date or _dt.datetime.now(_dt.timezone.utc)
    cols, rows, budgets, summary, figs = _tables(kind, result, unit)
    digest = hashlib.sha1(json.dumps(to_jsonable(result), sort_keys=True, default=str).encode()
                          + sensor_id.encode()).hexdigest()[:8].upper()
    cert_id = f"SC-{date.strftime('%Y%m%d')}-{digest}"
    return _TEMPLATE.render(
        title=_TITLES.get(kind, kind), cert_id=cert_id, sensor_id=sensor_id, model=model,
        date=date.strftime("%Y-%m-%d %H:%M UTC"), method=method, version=__version__,
        conditions=[(k, v if isinstance(v, str) else _g(v)) for k, v in (conditions or {}).items()],
        summary=summary, columns=cols, rows=rows, budgets=[b for b in budgets if b[0]],
        plots=[svg_inline(f) for f in figs], files=", ".join(files) or "-",
        warnings=list(getattr(result, "warnings", ()) if warnings is None else warnings),
    )


def write_certificate(path: str | Path, kind: str, result: Any, **kw: Any) -> Path:
    """Write :func:`certificate_html` to ``path`` (folders created) and return the path."""
    from senscal.io.guard import check_output, write_text

    path = check_output(path, what="report")
    write_text(path, certificate_html(kind, result, **kw), what="report")
    return path
