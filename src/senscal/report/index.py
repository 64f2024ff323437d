"""The demo's ``index.html``: one self-contained page, plots embedded."""

from __future__ import annotations

import datetime as _dt
import html
from pathlib import Path
from typing import Sequence

import jinja2

from senscal.report.plots import png_data_uri

_TEMPLATE = jinja2.Template(
    """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>senscal demo</title>
<style>
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;max-width:1000px;margin:2em auto;padding:0 1em;color:#222}
h1{margin-bottom:0}.sub{color:#666;margin-top:.2em}
section{border-top:1px solid #ddd;margin-top:2em;padding-top:1em}
table{border-collapse:collapse;margin:.8em 0}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f4f4f4}td:first-child,th:first-child{text-align:left}
img{max-width:100%;border:1px solid #eee}
nav a{margin-right:1em}
td.note{text-align:left;font-size:.85em;color:#555;max-width:22em}
</style></head><body>
<h1>senscal demo</h1>
<p class="sub">Every job run on simulated data with known truth &middot; {{ when }} &middot; seed {{ seed }}</p>
<nav>{% for s in sections %}<a href="#{{ s.key }}">{{ s.title }}</a>{% endfor %}</nav>
{% for s in sections %}
<section id="{{ s.key }}"><h2>{{ s.title }}</h2>
<p>{{ s.summary }}</p>
{% if s.rows %}{% set notes = s.rows | selectattr("note", "defined") | list %}<table><tr><th>quantity</th><th>truth</th><th>estimate</th><th>u (k=1)</th><th>U (k=2)</th><th>unit</th>{% if notes %}<th>note</th>{% endif %}</tr>
{% for r in s.rows %}<tr><td>{{ r.quantity }}</td><td>{{ fmt(r.truth) }}</td><td>{{ fmt(r.estimate) }}</td><td>{{ fmtu(r.uncertainty) }}</td><td>{{ fmt2(r.uncertainty) }}</td><td>{{ r.unit or "" }}</td>{% if notes %}<td class="note">{{ r.note or "" }}</td>{% endif %}</tr>
{% endfor %}</table>{% endif %}
{% for t in s.tables %}<h3>{{ t.title }}</h3><table><tr>{% for c in t.columns %}<th>{{ c }}</th>{% endfor %}</tr>
{% for row in t.rows %}<tr>{% for v in row %}<td>{{ fmt(v) }}</td>{% endfor %}</tr>{% endfor %}</table>{% endfor %}
{% if s.plot %}<p><img alt="{{ s.title }} plot" src="{{ img(s.plot) }}"></p>{% endif %}
{% if s.files %}<p>Outputs: {% for f in s.files %}<a href="{{ f }}">{{ f }}</a> {% endfor %}</p>{% endif %}
</section>
{% endfor %}
</body></html>
""",
    autoescape=True,
)


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    try:
        return f"{float(v):.6g}"
    except (TypeError, ValueError):
        return html.escape(str(v))


def write_index(sections: Sequence, out: Path, *, seed: int | None = None) -> Path:
    """Write ``out/index.html`` for the demo sections and return its path."""
    out = Path(out)

    def img(rel: str) -> str:
        p = out / rel
        return png_data_uri(p) if p.suffix.lower() == ".png" else rel

    text = _TEMPLATE.render(sections=sections, fmt=_fmt,
                            # Uncertainties to two significant digits (GUM 7.2.6).
                            fmtu=lambda u: "-" if u is None else f"{float(u):.2g}",
                            fmt2=lambda u: "-" if u is None else f"{2 * float(u):.2g}",
                            img=img, seed=seed if seed is not None else "",
                            when=_dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"))
    from senscal.io.guard import write_text

    # atomic: an interrupted demo never leaves half a page that links to missing outputs
    return write_text(out / "index.html", text, what="demo index")
