"""Calibration certificates (HTML and PDF) for the vibration jobs.

One self-contained page (plots inlined as SVG, no scripts, no network) that
states what ISO/IEC 17025:2017 7.8.2.1 and 7.8.4.1 require: title, the
laboratory's name and address, where the calibration was done, a unique id
and "page x of y" on every page (PDF), the customer, the method and
procedure, the item (description, manufacturer, model, serial), the dates of
calibration and issue, the results with units and expanded uncertainties
(k=2), the environmental conditions with their uncertainties, the reference
standards with their own certificates and traceability, deviations from the
method, a statement of conformity with its decision rule when one was asked
for, who authorises the certificate, and the statement that the results
relate only to the item calibrated.  The lab and run fields come from a
:class:`senscal.report.lab.CertificateInfo`; when a required one is missing
the certificate says DRAFT on every page and :func:`certificate_warnings`
returns the ``certificate-draft`` warning naming them.  A field is never
printed as "not stated".

The PDF (:mod:`senscal.report.pdf`) is rendered from the same HTML by
WeasyPrint: its ``@page`` rules put the certificate id, "page x of y" and the
DRAFT mark in the page margins.

References
----------
.. [1] ISO/IEC 17025:2017, 7.8 (reporting of results; calibration
   certificates).
.. [2] JCGM 100:2008 (GUM), 7.2 (reporting expanded uncertainty).
"""

from __future__ import annotations

import base64
import datetime as _dt
import hashlib
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import jinja2
import numpy as np

from senscal._result import to_jsonable
from senscal.errors import InputError
from senscal.report.lab import CertificateInfo, missing_fields, signing_approvers, traceability_claim
from senscal.report.plots import SUPERSCRIPT_DIGITS, new_figure, svg_inline

__all__ = ["write_certificate", "certificate_bytes", "certificate_html", "certificate_id", "certificate_warnings", "budget_warnings",
           "REPORT_SUFFIXES", "response_figure", "linearity_figure", "velocity_figure"]

# What --report writes, by suffix.
REPORT_SUFFIXES = (".html", ".htm", ".pdf")

_TEMPLATE = jinja2.Template(
    """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Calibration certificate {{ cert_id }}</title>
<meta name="author" content="{{ lab.name }}"><meta name="generator" content="senscal {{ version }}">
<style>
@page{size:A4;margin:20mm 16mm 20mm 16mm;font-family:"DejaVu Sans",Helvetica,Arial,sans-serif;
 @top-left{content:string(labname);font-size:8pt;color:#555}
 @top-right{content:string(draftmark);font-size:10pt;font-weight:bold;color:#b00}
 @bottom-left{content:"Certificate " string(certid);font-size:8pt;color:#333}
 @bottom-right{content:"Page " counter(page) " of " counter(pages);font-size:8pt;color:#333}}
body{font-family:"DejaVu Sans",system-ui,Segoe UI,Helvetica,Arial,sans-serif;color:#222;font-size:10pt}
@media screen{body{max-width:960px;margin:2em auto;padding:0 1em;font-size:11pt}}
header{display:flex;justify-content:space-between;align-items:flex-start;border-bottom:2px solid #333;padding-bottom:.4em}
.lab .labname{font-size:13pt;font-weight:700;string-set:labname content()}
.lab div{white-space:pre-line}
.logo img{max-height:22mm;max-width:60mm}
h1{margin:.5em 0 .1em;font-size:18pt}h2{font-size:12pt;margin:1.1em 0 .3em;break-after:avoid}
.sub{color:#555;margin-top:0}.certid{string-set:certid content();font-weight:700}
table{border-collapse:collapse;margin:.4em 0 .9em}td,th{border:1px solid #bbb;padding:.2em .5em;text-align:right;vertical-align:top}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}tr{break-inside:avoid}thead{display:table-header-group}
table.kv{width:100%}table.kv td{text-align:left;white-space:pre-line}table.kv td:first-child{font-weight:600;background:#fafafa;width:32%}
table.small{font-size:8pt;break-inside:avoid}table.small td,table.small th{padding:.15em .35em}
.missing{color:#b00;font-weight:700}
.draft{border:2px solid #b00;color:#b00;padding:.4em .6em;margin:.6em 0;string-set:draftmark "DRAFT"}
.watermark{position:fixed;top:38%;left:0;width:100%;text-align:center;font-size:110pt;font-weight:700;
 color:rgba(190,0,0,.13);transform:rotate(-35deg);z-index:-1}
.plot,.results,li{break-inside:avoid}.plot svg{width:100%;height:auto}
.note{border-top:1px solid #ccc;margin-top:1.5em;padding-top:.5em;font-size:.92em;color:#333;break-inside:avoid}
.sign{margin-top:1em}.sign td{border:none;padding:.2em 1.5em .2em 0;text-align:left}
.end{text-align:center;color:#555;margin-top:1em}
</style></head><body>
{% if draft %}<div class="watermark">DRAFT</div>{% endif %}
<header><div class="lab"><div class="labname">{{ lab.name or "Laboratory name missing" }}</div>
<div>{{ lab.address }}</div>
{% if lab.accreditation %}<div>Accreditation: {{ lab.accreditation }}</div>{% endif %}
{% if lab.phone or lab.email %}<div>{{ lab.phone }}{% if lab.phone and lab.email %} &middot; {% endif %}{{ lab.email }}</div>{% endif %}
</div>{% if logo %}<div class="logo"><img alt="logo" src="{{ logo }}"></div>{% endif %}</header>
<h1>Calibration certificate</h1>
<p class="sub">{{ title }} &middot; certificate <span class="certid">{{ cert_id }}</span></p>
{% if draft %}<div class="draft"><b>DRAFT: not valid as a calibration certificate.</b> Required fields are missing:
{{ missing | join(", ") }}.</div>{% endif %}
<table class="kv">
<tr><td>Certificate id</td><td>{{ cert_id }}</td></tr>
{% for label, value in admin %}<tr><td>{{ label }}</td><td>{% if value is none %}<span class="missing">MISSING (required)</span>{% else %}{{ value }}{% endif %}</td></tr>
{% endfor %}</table>
<h2>Reference standards and traceability</h2>
{% if lab.standards %}<table class="small"><thead><tr><th>standard</th><th>serial</th><th>its certificate</th><th>traceable to</th><th>calibration due</th><th>u (rel., k=1)</th></tr></thead>
{% for s in lab.standards %}{% set st = s.due_status(run.calibration_date) %}<tr><td>{{ s.name }}</td><td>{{ s.serial or "-" }}</td><td>{{ s.certificate or "-" }}</td><td>{{ s.traceability or "-" }}</td><td>{% if st == "missing" %}<span class="missing">MISSING</span>{% elif st == "overdue" %}{{ s.due }} <span class="missing">OVERDUE</span>{% else %}{{ s.due }}{% endif %}</td><td>{{ pct(s.u_relative) }}</td></tr>
{% endfor %}</table>
<p>{{ trace_text }}</p>
{% else %}<p class="missing">MISSING (required): the reference standards and their traceability.</p>{% endif %}
<h2>Environmental conditions</h2>
{% if env %}<table><thead><tr><th>quantity</th><th>value</th><th>U (k=2)</th><th>unit</th></tr></thead>
{% for c in env %}<tr><td>{{ c.name }}</td><td>{{ g(c.value) }}</td><td>{{ "-" if c.uncertainty is none else u(2 * c.uncertainty) }}</td><td>{{ punit(c.unit) }}</td></tr>
{% endfor %}</table>{% else %}<p class="missing">MISSING (required): the environmental conditions of the calibration.</p>{% endif %}
<h2>Calibration settings</h2>
<table class="kv">{% for k, v in conditions %}<tr><td>{{ k }}</td><td>{{ v }}</td></tr>{% endfor %}</table>
<div class="results"><h2>Results</h2>
{% for s in summary %}<p><b>{{ s[0] }}</b>: {{ s[1] }}</p>{% endfor %}
<table><thead><tr>{% for c in columns %}<th>{{ c }}</th>{% endfor %}</tr></thead>
{% for row in rows %}<tr>{% for v in row %}<td>{{ v }}</td>{% endfor %}</tr>{% endfor %}</table>
<p>U is the expanded uncertainty with coverage factor k = 2 (about 95 % coverage for a normal
distribution), evaluated following the GUM (JCGM 100:2008) from the standard uncertainties below;
where the effective degrees of freedom are few, k is Student's t for the same 95.45 % (shown in the budget).</p></div>
{% for p in plots %}<div class="plot">{{ p | safe }}</div>{% endfor %}
<h2>Deviations from the method</h2>
<p>{{ run.deviations or "None: the calibration followed the method as stated." }}</p>
{% if run.conformity %}<h2>Statement of conformity</h2>
<p>{{ run.conformity }}</p>
<p>Decision rule: {% if run.decision_rule %}{{ run.decision_rule }}{% else %}<span class="missing">MISSING (required with a statement of conformity)</span>{% endif %}</p>{% endif %}
{% if warnings %}<h2>Warnings</h2>
<p>The data depart from the method's model as follows; the uncertainties above do not cover these departures.</p>
<ul>{% for w in warnings %}<li>{{ w }}</li>{% endfor %}</ul>{% endif %}
{% if run.remarks %}<h2>Remarks</h2><p>{{ run.remarks }}</p>{% endif %}
{% if budgets %}<h2>Uncertainty budget (standard uncertainties, k = 1)</h2>{% endif %}
{% for bcols, brows in budgets %}<table class="small"><thead><tr>{% for c in bcols %}<th>{{ c }}</th>{% endfor %}</tr></thead>
{% for row in brows %}<tr>{% for v in row %}<td>{{ v }}</td>{% endfor %}</tr>{% endfor %}</table>{% endfor %}
<div class="note">
<p>The results relate only to the item calibrated, under the conditions stated above.
This certificate shall not be reproduced except in full without the written approval of the laboratory.</p>
<p>Records: {{ files }}. Software: senscal {{ version }}.</p>
<table class="sign"><tr><td><b>Authorised by</b></td>
{% for a in approvers %}<td>{{ a.name }}{% if a.role %}<br>{{ a.role }}{% endif %}<br>Date: {{ issued }}</td>{% else %}<td><span class="missing">MISSING (required): the person who authorises the certificate</span></td>{% endfor %}</tr></table>
<p class="end">End of certificate {{ cert_id }}</p>
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


def _decimals_of(U: float) -> int:
    """The decimal position of the second significant digit of ``U`` (negative: tens, hundreds...)."""
    return 1 - math.floor(math.log10(abs(U)))


def value_and_u(value: Any, U: Any) -> tuple[str, str]:
    """A value rounded to the last digit of its uncertainty, and that uncertainty (GUM 7.2.6).

    ``U`` keeps two significant digits and ``value`` is rounded at the
    same decimal position, so ``0.0499999 +- 0.0002`` reads
    ``0.050000``/``0.00020``.  Plain decimal notation is used between
    1e-5 and 1e7, scientific notation outside (with the same number of
    digits after the uncertainty's leading ones).

    Parameters
    ----------
    value, U : float
        The value and its (expanded or standard) uncertainty, same unit.

    Returns
    -------
    tuple of str
        ``(value_text, U_text)``; a missing or non-finite ``U`` gives
        the value with 6 significant digits and ``"-"``.
    """
    try:
        v, u = float(value), float(U)
    except (TypeError, ValueError):
        return _g(value), _u(U)
    if not math.isfinite(v):
        return "-", _u(u)
    if not (math.isfinite(u) and u > 0):
        return _g(v), "-" if not math.isfinite(u) else _g(u, 2)
    # Round U first: 0.00996 -> 0.010 moves its second digit one place left.
    d = _decimals_of(u)
    u_r = round(u, d)
    if u_r > 0:
        d = _decimals_of(u_r)
        u_r = round(u, d)
    big = max(abs(v), u_r)
    if 1e-5 <= big < 1e7:
        dd = max(d, 0)
        return f"{round(v, d):.{dd}f}", f"{u_r:.{dd}f}"
    # scientific: the value's exponent sets the mantissa, digits down to U's second significant one
    e = math.floor(math.log10(big))
    digits = max(e + d, 1)
    return f"{v:.{digits}e}", f"{u_r:.{max(digits - (e - math.floor(math.log10(u_r))), 1)}e}"


def pretty_unit(unit: str) -> str:
    """A unit as a certificate prints it: ``m/s^2`` -> ``m/s²``, ``degC`` -> ``°C``, ``deg`` -> ``°``.

    Only the typography changes (the DCC keeps the D-SI form); ``1`` and
    an empty unit stay as they are.
    """
    import re

    if not unit:
        return unit
    out = re.sub(r"\^(?:\((-?\d+)\)|(-?\d+))", lambda m: (m.group(1) or m.group(2)).translate(SUPERSCRIPT_DIGITS), unit)
    out = re.sub(r"\bdegC\b", "°C", out)
    out = re.sub(r"\bdeg\b", "°", out)
    return out.replace("*", "·")


def _plain_log_ticks(ax) -> None:
    """Tick labels 1, 10, 100 on a log axis: the default ones are TeX, which literal (user-safe) text shows raw."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def response_figure(resp):
    """Bode plot: (normalised) sensitivity and phase delay vs log frequency, with U (k=2) as bars and bands."""
    pts = resp.points
    f = np.array([p.frequency for p in pts])
    order = np.argsort(f)
    norm = all(p.normalized_sensitivity is not None for p in pts)
    mag = np.array([p.normalized_sensitivity if norm else p.sensitivity for p in pts], dtype=float)
    umag = np.array([p.u_normalized_sensitivity if norm else p.u_sensitivity for p in pts], dtype=float)
    has_ph = all(p.phase_delay is not None for p in pts)
    fig, ax = new_figure(2 if has_ph else 1, 1, width=7.0, height=4.8 if has_ph else 2.8, sharex=True, squeeze=False)
    ax = ax[:, 0]
    series = [(mag, umag, "o-", "C0", "S_i / S_0" if norm else f"sensitivity ({resp.unit})")]
    if has_ph:
        series.append((np.degrees([p.phase_delay for p in pts]), np.degrees([p.u_phase_delay for p in pts]), "s-",
                       "C1", "phase delay (deg)"))
    for a, (y, uy, fmt, colour, label) in zip(ax, series):
        a.fill_between(f[order], (y - 2 * uy)[order], (y + 2 * uy)[order], color=colour, alpha=0.2, lw=0,
                       label="U band (k=2)")
        a.errorbar(f[order], y[order], yerr=2 * uy[order], fmt=fmt, color=colour, capsize=3, ms=4)
        a.set_xscale("log")
        a.set_ylabel(label)
        a.grid(True, which="both", alpha=0.3)
    ax[0].set_title("Frequency response (bars and bands: U, k=2)")
    ax[0].legend(loc="best", fontsize="small")
    _plain_log_ticks(ax[-1])
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
    """One budget table per quantity, GUM-style: a row per component, a column per point.

    Points as columns keep the table narrow on an A4 page (the wide form, a
    column per component, was cramped with five components); the value is
    rounded to the last digit of its U.
    """
    pairs = [(lab, b) for lab, b in zip(labels, budgets) if b is not None]
    if not pairs:
        return [], []
    sources: list[tuple[str, str]] = []
    for _, b in pairs:
        for c in b.components:
            if (c.source, c.kind) not in sources:
                sources.append((c.source, c.kind))
    b0 = pairs[0][1]
    cols = [f"{b0.quantity} ({pretty_unit(b0.unit)})" if b0.unit and b0.unit != "1" else b0.quantity]
    cols += [lab for lab, _ in pairs]
    rows = [["value"] + [value_and_u(b.value, b.expanded)[0] for _, b in pairs]]
    for src, kind in sources:
        cells = []
        for _, b in pairs:
            comp = next((c for c in b.components if (c.source, c.kind) == (src, kind)), None)
            cells.append("-" if comp is None else _u(comp.standard_uncertainty))
        # sources that already say their type ("output fit (type A)") are not labelled twice
        rows.append([src if f"type {kind}" in src else f"{src} (type {kind})"] + cells)
    rows.append(["combined standard uncertainty u_c"] + [_u(b.combined) for _, b in pairs])
    rows.append(["coverage factor k"] + [_g(b.coverage_factor, 3) for _, b in pairs])
    rows.append(["expanded uncertainty U = k u_c"] + [_u(b.expanded) for _, b in pairs])
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
        cols = ["frequency (Hz)", f"sensitivity ({pretty_unit(unit)})", "U"]
        cols += ["S_i / S_0", "U"] if norm else []
        cols += ["phase delay (°)", "U (°)"] if has_ph else []
        rows = []
        for p in pts:
            r = [_g(p.frequency), *value_and_u(p.sensitivity, 2 * p.u_sensitivity)]
            if norm:
                r += [*value_and_u(p.normalized_sensitivity, 2 * p.u_normalized_sensitivity)]
            if has_ph:
                r += [*value_and_u(math.degrees(p.phase_delay), 2 * math.degrees(p.u_phase_delay))]
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
        cols = ["frequency (Hz)", f"sensitivity ({pretty_unit(unit)})", "U", "phase vs velocity (°)", "U (°)"]
        rows = [[_g(p.frequency), *value_and_u(p.sensitivity, 2 * p.u_sensitivity),
                 *value_and_u(math.degrees(p.phase), 2 * math.degrees(p.u_phase))] for p in result.points]
        budgets = [_budget_table([p.budget for p in result.points], [f"{p.frequency:g} Hz" for p in result.points]),
                   _budget_table([result.budget], ["mean"])]
        sv, sU = value_and_u(result.sensitivity, result.budget.expanded)
        pu = pretty_unit(unit)
        summary = [("Mean sensitivity", f"{sv} {pu}, U = {sU} {pu} "
                    f"(k = {_g(result.budget.coverage_factor, 3)}); standard deviation over {len(result.points)} "
                    f"points {_u(result.sensitivity_std)} {pu}")]
        figs = [velocity_figure(result)]
    elif kind == "linearity":
        out_unit = unit.split("/(m/s^2)")[0] if unit else ""
        cols = ["input amplitude (m/s²)", f"output amplitude ({pretty_unit(out_unit)})" if out_unit
                else "output amplitude", "U", "deviation", "deviation (% FS)"]
        rows = [[_g(p.input_amplitude), *value_and_u(p.output_amplitude, 2 * p.u_output_amplitude),
                 _g(p.deviation, 3), _g(p.deviation_percent, 3)] for p in result.points]
        budgets = []
        k = getattr(result, "coverage_factor", 2.0)
        if getattr(result, "linearity_resolved", None) is False:
            lin_text = (f"below {_g(result.linearity_bound_percent, 2)} % of full-scale output "
                        f"({_g(result.full_scale_output)}): not resolved, the largest deviation "
                        f"{_g(result.linearity_percent, 2)} % is within the noise")
        else:
            lin_text = (f"{_g(result.linearity_percent, 3)} % of full-scale output ({_g(result.full_scale_output)}), "
                        f"U = {_u(2 * result.u_linearity_percent)} % (k=2, Monte Carlo, JCGM 101)")
        slope_v, slope_U = value_and_u(result.slope, k * result.u_slope)
        icpt_v, icpt_U = value_and_u(result.intercept, k * result.u_intercept)
        summary = [("Amplitude linearity", lin_text),
                   ("Sensitivity (slope)", f"{slope_v} {pretty_unit(unit)}, U = {slope_U} (k = {_g(k, 3)})"),
                   ("Intercept", f"{icpt_v}, U = {icpt_U} (k = {_g(k, 3)})")]
        figs = [linearity_figure(result, f"({out_unit})" if out_unit else "")]
    elif kind == "imu":
        cols, rows, budgets, summary, figs = _imu_tables(result)
    elif kind == "shock":
        cols, rows, budgets, summary, figs = _shock_tables(result, unit)
    else:
        raise InputError(f"unknown certificate kind {kind!r}; use response, velocity, linearity, imu or shock")
    return cols, rows, budgets, summary, figs


def _shock_labels(job) -> list[str]:
    return [f"{src} #{p.index}" for src, p in zip(job.sources, job.pulses)]


def _shock_tables(job, unit: str):
    """Results, budgets, summary and figure of a shock certificate (``senscal.jobs.shock.ShockResult``)."""
    from senscal.shock.plots import shock_figure

    cols = ["record, pulse", "duration (ms)", "peak acceleration (m/s²)", "U", f"shock sensitivity ({pretty_unit(unit)})",
            "U"]
    rows = [[lab, _g(p.duration_ms, 3), *value_and_u(abs(p.peak_acceleration), 2 * p.u_peak_acceleration),
             *value_and_u(p.sensitivity, 2 * p.u_sensitivity)] for lab, p in zip(_shock_labels(job), job.pulses)]
    labels = _shock_labels(job)
    budgets = [_budget_table(list(job.budgets(unit.split("/(m/s^2)")[0] or None)), labels)]
    summary = [("Shock sensitivity", "ratio of the output's peak to the peak acceleration, each the vertex of a "
                "4th-degree polynomial through the samples above 80 % of the peak"),
               ("Filter", job.filter),
               ("Transfer function", "ratio of the spectra of the output and the acceleration over each pulse "
                "and its settling (figure; values in the JSON result)")]
    figs = [shock_figure(job.pulses, pretty_unit(unit), labels)]
    return cols, rows, budgets, summary, figs


def _imu_budgets(job) -> list[tuple[str, list[Any]]]:
    """(title, budgets per axis or angle) of an IMU calibration (``senscal.jobs.imu.ImuCalibrateResult``)."""
    from senscal.imu import GYRO_ANGLES
    from senscal.vibration.budget import make_budget

    d, bud = job.to_dict(), job.budget()
    g = d["gyroscope"]
    unit = g["scale_unit"]
    scale = [make_budget("gyro scale", g["scale"][i], unit, [(c["source"], c["type"], c["u_scale"][i])
                                                              for c in bud["gyroscope"]], 2.0) for i in range(3)]
    ang = [make_budget("gyro misalignment", g["misalignment_deg"][n]["value"], "deg",
                       [(c["source"], c["type"], c["u_misalignment_deg"][j]) for c in bud["gyroscope"]], 2.0)
           for j, n in enumerate(GYRO_ANGLES)]
    return [("scale", scale), ("angle", ang)]


def _imu_tables(job):
    """Results, budgets, summary and figure of an IMU calibration certificate."""
    from senscal.imu import GYRO_ANGLES
    from senscal.imu.plots import imu_figure

    d = job.to_dict()
    cols = ["quantity", "value", "U (k=2)", "unit"]
    qs = sorted(job.quantities(), key=lambda q: not q.name.startswith("accel"))  # the accelerometer's first
    rows = [[q.name, *value_and_u(q.value, q.k * q.uncertainty), pretty_unit(q.unit)] for q in qs]
    (_, scale), (_, ang) = _imu_budgets(job)
    budgets = [_budget_table(scale, ["x", "y", "z"]), _budget_table(ang, list(GYRO_ANGLES))]
    st, gd, a = d["static"], d["gravity_direction_residual_deg"], d["accelerometer"]
    summary = [("Static poses", f"{st['n_poses']} (threshold x{st['threshold_multiple']:g} the still variance); "
                                f"|f| - g spread after calibration {_g(a['g_spread']['std'], 3)} m/s²"),
               ("Gravity direction predicted at the next pose", f"rms {_g(gd['rms_before'], 3)}° with the nominal "
                f"gyroscope, {_g(gd['rms_after'], 3)}° calibrated")]
    rt = d.get("rate_table")
    if rt is not None:
        c = rt["consistency"]
        summary.append(("Rate table", f"{rt['n_segments']} segments of known rate combined with the multi-pose "
                        f"estimate; consistency chi² {_g(c['chi2'], 3)} for {c['dof']} degrees of freedom"))
    te = d.get("temperature")
    if te is not None:
        summary.append(("Reference temperature", f"{_g(te['reference'], 4)} {pretty_unit(te['unit'] or '')}: "
                        "biases and scales hold there"))
    r = job.result
    figs = [imu_figure(job.g_before, job.g_after, r.residual_before_deg, r.residual_after_deg,
                       temperature=job.pose_temperature, temp_unit=job.temp_unit)]
    return cols, rows, budgets, summary, figs


_TITLES = {"response": "Accelerometer frequency response", "velocity": "Velocity-sensor sensitivity",
           "linearity": "Accelerometer amplitude linearity",
           "imu": "IMU accelerometer and gyroscope", "shock": "Accelerometer shock sensitivity"}

# The option that sets each type B component, for the budget-zero-component hint.
_B_OPTIONS = {"input amplitude": "--u-input", "reference sensitivity": "--u-reference",
              "static sensitivity S0": "--u-static-sensitivity", "input phase": "--u-initial-phase-deg",
              "position reference": "--u-position", "laser wavelength": "--u-wavelength-rel",
              "output voltage amplitude measurement": "--u-gain-rel",
              "output voltage phase measurement": "--u-gain-phase-deg",
              "other effects (transverse, rocking, base strain, mounting)": "--u-other-rel",
              "table rate, stated u (type B)": "u_rate in --rate-table",
              "table axis alignment, stated u (type B)": "u_axis in --rate-table",
              "reference accelerometer's sensitivity (its calibration, ISO 16063-22)": "--u-reference",
              "other effects (transverse motion, mounting, amplitude linearity)": "--u-other"}


def _budgets(kind: str, result: Any) -> list[tuple[str, Any]]:
    """Every (label, budget) a certificate of ``kind`` shows."""
    if kind == "response":
        return [(f"{p.frequency:g} Hz", b) for p in result.points
                for b in (p.sensitivity_budget, p.normalized_budget, p.phase_delay_budget) if b is not None]
    if kind == "velocity":
        return [(f"{p.frequency:g} Hz", p.budget) for p in result.points] + [("mean", result.budget)]
    if kind == "imu":
        from senscal.imu import GYRO_ANGLES

        (_, scale), (_, ang) = _imu_budgets(result)
        return list(zip(("x", "y", "z"), scale)) + list(zip(GYRO_ANGLES, ang))
    if kind == "shock":
        return list(zip(_shock_labels(result), result.budgets()))
    return []


def _sensitivity_u(kind: str, result: Any) -> list[tuple[str, float]]:
    """(label, relative standard uncertainty) of each absolute sensitivity: what a reference standard bounds."""
    if kind == "linearity":
        return [("slope", abs(result.u_slope / result.slope))] if result.slope else []
    return [(f"{b.quantity} at {label}" if label != "mean" else b.quantity, abs(b.combined / b.value))
            for label, b in _budgets(kind, result) if b.quantity in ("sensitivity", "mean sensitivity", "shock sensitivity") and b.value]


def budget_warnings(kind: str, result: Any, standards: Sequence[Any] = ()) -> tuple[str, ...]:
    """Sanity of the uncertainty budget a certificate states.

    Parameters
    ----------
    kind : str
        ``"response"``, ``"velocity"`` or ``"linearity"``.
    result : object
        The job's result (FrequencyResponse, VelocityCalibration, AmplitudeLinearity).
    standards : sequence of Standard
        The lab's reference standards; those with ``u_relative`` bound the result.

    Returns
    -------
    tuple of str
        ``budget-zero-component`` when a type B component is 0 (the
        certificate's U then leaves that input out, e.g. an input amplitude
        taken as exact); ``u-below-reference`` when an absolute sensitivity's
        combined relative standard uncertainty is below a reference
        standard's own ``u_relative`` (a calibration cannot be better than
        the standard it is traced to; the budget misses that standard).
    """
    from senscal.diagnostics import named

    out = []
    zero: dict[str, list[str]] = {}
    for label, b in _budgets(kind, result):
        for c in b.components:
            if c.kind == "B" and c.standard_uncertainty == 0:
                zero.setdefault(c.source, [])
                if b.quantity not in zero[c.source]:
                    zero[c.source].append(b.quantity)
    if zero:
        listed = "; ".join(f"'{src}'{' (' + _B_OPTIONS[src] + ')' if src in _B_OPTIONS else ''} in the budget of "
                           f"{', '.join(qs)}" for src, qs in zero.items())
        out.append(named("budget-zero-component", (
            f"type B component(s) given as 0: {listed}; the stated U treats those inputs as exact: give their "
            "standard uncertainties, or the certificate understates U")))
    refs = [s for s in standards if getattr(s, "u_relative", None)]
    if refs:
        worst = max(refs, key=lambda s: s.u_relative)
        below = [(lab, u) for lab, u in _sensitivity_u(kind, result) if u < worst.u_relative]
        if below:
            lab, u = min(below, key=lambda x: x[1])
            out.append(named("u-below-reference", (
                f"{len(below)} result(s) have a relative standard uncertainty below that of the reference standard "
                f"'{worst.name}' ({100 * worst.u_relative:.2g} %), e.g. {lab}: {100 * u:.2g} %; a calibration cannot "
                "be better than its reference: add the reference's uncertainty to the budget (--u-input, "
                "--u-reference, --u-position)")))
    return tuple(out)


def certificate_warnings(kind: str, result: Any, info: CertificateInfo) -> tuple[str, ...]:
    """What a lab must hear before it issues the certificate: ``certificate-draft`` and the budget checks.

    ``certificate-draft`` names the required fields that are missing
    (:func:`senscal.report.lab.missing_fields`): the certificate says DRAFT
    on every page until they are given.
    """
    from senscal.diagnostics import named

    miss = missing_fields(info)
    out = [named("certificate-draft", (
        f"the certificate is marked DRAFT: required field(s) missing: {', '.join(miss)}; give them in the lab "
        "profile (--lab FILE or $SENSCAL_LAB), a run file (--run FILE) or the certificate options"))] if miss else []
    for st in info.lab.standards:
        status = st.due_status(info.run.calibration_date)
        if status:
            out.append(named("reference-standard-due", (
                f"reference standard '{st.name}': " + ("no calibration due date is stated; give 'due' in the lab "
                                                       "profile's [[standards]]" if status == "missing" else
                                                       f"its calibration was due {st.due}, before the calibration "
                                                       f"date {info.run.calibration_date}: recalibrate it or use "
                                                       "another standard"))))
    return tuple(out) + budget_warnings(kind, result, info.lab.standards)


def certificate_id(kind: str, result: Any, info: CertificateInfo, date: _dt.datetime) -> str:
    """The run's ``certificate_id``, else ``SC-YYYYMMDD-XXXXXXXX`` from the date and a digest of result and item."""
    if info.run.certificate_id:
        return info.run.certificate_id
    item = f"{info.run.serial}|{info.run.model}|{kind}"
    digest = hashlib.sha1(json.dumps(to_jsonable(result), sort_keys=True, default=str).encode()
                          + item.encode()).hexdigest()[:8].upper()
    return f"SC-{date.strftime('%Y%m%d')}-{digest}"


def _logo_uri(path: str) -> str:
    """The lab logo as a ``data:`` URI (the certificate stays one self-contained file)."""
    if not path:
        return ""
    mime = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".svg": "image/svg+xml",
            ".gif": "image/gif"}.get(Path(path).suffix.lower())
    if mime is None:
        raise InputError(f"lab logo {path}: use a .png, .jpg, .svg or .gif image")
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read the lab logo {path} ({exc.strerror or exc}); fix 'logo' in the lab profile") from None
    return f"data:{mime};base64," + base64.b64encode(data).decode()


def _admin_rows(info: CertificateInfo, method: str, issued: str) -> list[tuple[str, str | None]]:
    """The administrative fields in print order; ``None`` marks a missing required field."""
    run, lab = info.run, info.lab
    miss = set(missing_fields(info))

    def field_(name: str, text: str) -> str | None:
        return None if name in miss else text

    make = " ".join(x for x in (run.manufacturer, run.model) if x)
    rows = [("Customer", field_("run.customer", "\n".join(x for x in (run.customer, run.customer_address,
                                                                       run.customer_email) if x))),
            ("Item calibrated", field_("run.item", run.item))]
    if make:
        rows.append(("Manufacturer, model", make))
    rows += [("Serial number", field_("run.serial", run.serial)),
            ("Date(s) of calibration", field_("run.calibration_date", run.calibration_date))]
    if run.receipt_date:
        rows.append(("Date of receipt of the item", run.receipt_date))
    rows += [("Date of issue", issued),
             ("Location of the calibration", field_("run.location", run.location)),
             ("Method", "; ".join(x for x in (f"procedure {lab.procedure}" if lab.procedure else "", method) if x)
              or None)]
    return rows


def certificate_html(kind: str, result: Any, *, info: CertificateInfo | None = None, sensor_id: str = "",
                     model: str = "", method: str = "", conditions: Mapping[str, Any] | None = None, unit: str = "",
                     files: Sequence[str] = (), date: _dt.datetime | None = None,
                     warnings: Sequence[str] | None = None) -> str:
    """Render a certificate as one self-contained HTML string (the PDF is printed from it).

    Parameters
    ----------
    kind : str
        ``"response"`` (FrequencyResponse), ``"velocity"`` (VelocityCalibration)
        or ``"linearity"`` (AmplitudeLinearity).
    result : object
        The result of that job.
    info : CertificateInfo, optional
        Lab profile and run fields. Required fields it lacks are shown as
        MISSING and the certificate is marked DRAFT on every page.
    sensor_id, model : str
        Serial number and model of the item, used where ``info`` has none.
    method : str
        Method statement (the lab's procedure id is prefixed).
    conditions : mapping
        Settings of the calibration (shown as given).
    unit : str
        Sensitivity unit.
    files : sequence of str
        Records used.
    date : datetime, optional
        Date of issue (default: the run's ``issue_date``, else now, UTC).
    warnings : sequence of str, optional
        Named warnings to print on the certificate (default: the result's
        own ``warnings``).
    """
    from senscal import __version__

    info = info or CertificateInfo()
    run = info.run
    fill = {k: v for k, v in (("serial", sensor_id), ("model", model)) if v and not getattr(run, k)}
    if fill:
        info = replace(info, run=replace(run, **fill))
    if date is None and info.run.issue_date:
        try:
            date = _dt.datetime.fromisoformat(info.run.issue_date)
        except ValueError:
            raise InputError(f"issue_date {info.run.issue_date!r} is not an ISO 8601 date (YYYY-MM-DD)") from None
    date = date or _dt.datetime.now(_dt.timezone.utc)
    cols, rows, budgets, summary, figs = _tables(kind, result, unit)
    cert_id = certificate_id(kind, result, info, date)
    miss = missing_fields(info)
    return _utf8_checked(_TEMPLATE.render(
        title=_TITLES.get(kind, kind), cert_id=cert_id, lab=info.lab, run=info.run, logo=_logo_uri(info.lab.logo),
        admin=_admin_rows(info, method, date.strftime("%Y-%m-%d")), draft=bool(miss), missing=miss,
        issued=date.strftime("%Y-%m-%d"), trace_text=traceability_claim(info.lab.standards)[1], punit=pretty_unit,
        env=info.run.conditions, approvers=signing_approvers(info), version=__version__, g=_g, u=_u,
        pct=lambda v: "-" if v is None else f"{100 * v:.2g} %",
        conditions=[(k, v if isinstance(v, str) else _g(v)) for k, v in (conditions or {}).items()],
        summary=summary, columns=cols, rows=rows, budgets=[b for b in budgets if b[0]],
        plots=[svg_inline(f) for f in figs], files=", ".join(files) or "-",
        warnings=list(getattr(result, "warnings", ()) if warnings is None else warnings),
    ))


def _utf8_checked(html: str) -> str:
    """``html``, refused with one line when it holds text that is not Unicode (a non-UTF-8 byte in an argument)."""
    try:
        html.encode("utf-8")
    except UnicodeEncodeError as exc:
        near = html[max(exc.start - 30, 0):exc.start].rsplit(">", 1)[-1]
        raise InputError(f"certificate text after {near!r} holds bytes that are not UTF-8 text; give the option or "
                         "profile field as UTF-8") from None
    return html


def certificate_bytes(suffix: str, kind: str, result: Any, **kw: Any) -> bytes:
    """The certificate file's content: PDF for ``".pdf"``, UTF-8 HTML for ``".html"``/``".htm"``.

    Parameters
    ----------
    suffix : str
        The file suffix, case-insensitive.
    kind, result, **kw
        As :func:`certificate_html`.

    Raises
    ------
    InputError
        Another suffix, or bad certificate input.
    """
    suffix = suffix.lower()
    if suffix not in REPORT_SUFFIXES:
        raise InputError(f"a certificate is written as {', '.join(REPORT_SUFFIXES)}, not {suffix or '(no suffix)'!r}")
    html = certificate_html(kind, result, **kw)
    if suffix == ".pdf":
        from senscal.report.pdf import html_to_pdf

        return html_to_pdf(html)
    return html.encode("utf-8")


def write_certificate(path: str | Path, kind: str, result: Any, **kw: Any) -> Path:
    """Write the certificate to ``path``: PDF for ``.pdf``, HTML for ``.html``; folders created, written atomically.

    Parameters
    ----------
    path : path-like
        ``*.pdf`` or ``*.html`` (``*.htm``); any other suffix is refused.
    kind, result, **kw
        As :func:`certificate_html`.

    Raises
    ------
    InputError
        Another suffix, an unwritable folder, or a path that is an input of the command.
    """
    from senscal.io.guard import check_output, write_bytes

    path = check_output(path, suffixes=REPORT_SUFFIXES, what="report")
    write_bytes(path, certificate_bytes(path.suffix, kind, result, **kw), what="report")
    return path
