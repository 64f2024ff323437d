"""The Flask application of ``senscal registry serve``: server-rendered, read-only pages of a registry.

Pages (all GET; there is no endpoint that writes):

* ``/``: the hash-chain status, the sensors with their last calibration and
  due date (``OVERDUE`` / ``due soon`` marks), the reference standards with
  theirs.
* ``/sensors/SERIAL``: drift per quantity, the history plots (inline SVG,
  drawn by :func:`senscal.registry.plot.history_figure`), every calibration.
* ``/calibrations/UID``: one record: quantities, conditions, input files,
  standards used, its certificate files (download) and the record as JSON.
* ``/standards/IDENT``: a reference standard's certificates and every
  calibration that used it (the impact report).
* ``/chain``: ``senscal registry verify`` as a page.

Every page is one HTML document with its CSS inline and its plots as inline
SVG: nothing is fetched from the network (the Content-Security-Policy says
so to the browser too).  Due dates are those of ``senscal registry due``
(the drift line through a quantity's history reaching the tolerance), given
a tolerance (``tolerance``); without one the pages show the drift only.
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import dataclass
from datetime import date, datetime, timedelta
from pathlib import Path
from typing import Any, Iterable

from senscal.errors import InputError, SenscalError, TooFewSamplesError
from senscal.registry.store import (Calibration, HistoryPoint, Registry, UnknownQuantityError, UnknownSensorError,
                                   drift_report, parse_date)

__all__ = ["ViewOptions", "create_app", "CERTIFICATE_TYPES", "certificate_files"]

#: Files a stored certificate reference may name, by suffix: (label, MIME type).
CERTIFICATE_TYPES = {
    ".pdf": ("PDF certificate", "application/pdf"),
    ".html": ("HTML certificate", "text/html"),
    ".htm": ("HTML certificate", "text/html"),
    ".xml": ("DCC (XML)", "application/xml"),
}
#: Plots drawn inline on a sensor page; further quantities have their own page.
MAX_INLINE_PLOTS = 8
#: Matplotlib figures are drawn one at a time (the server answers requests in threads).
_PLOT_LOCK = threading.Lock()


@dataclass(frozen=True)
class ViewOptions:
    """How the pages judge due dates.

    Attributes
    ----------
    tolerance : float or None
        Allowed relative deviation of every quantity from its first record
        (0.01 = 1 %), as ``senscal registry due --tolerance``; None shows the
        drift without due dates.
    k : float
        Coverage factor added to the predicted deviation (``registry due --k``).
    as_of : datetime or None
        The date "overdue" is judged at; None means the time of each request.
    soon_days : int
        A due date within this many days of ``as_of`` is marked "due soon".
    """

    tolerance: float | None = None
    k: float = 2.0
    as_of: datetime | None = None
    soon_days: int = 30

    def when(self) -> datetime:
        return self.as_of if self.as_of is not None else parse_date(None)


# --- what the pages show (plain dicts for the templates) ------------------------

def _status(due: datetime | date | None, as_of: datetime, soon_days: int, overdue: bool | None) -> str:
    """``"overdue"`` (as the registry judges it: ``overdue``), ``"soon"``, ``"ok"``, or ``""`` without a due date."""
    if overdue:
        return "overdue"
    if due is None:
        return ""
    day = due.date() if isinstance(due, datetime) else due
    return "soon" if day <= as_of.date() + timedelta(days=soon_days) else "ok"


_RANK = {"overdue": 3, "soon": 2, "ok": 1, "": 0}


def _quantity_drift(serial: str, quantity: str, points: list[HistoryPoint], opts: ViewOptions,
                    as_of: datetime) -> dict[str, Any]:
    """Drift and due date of one quantity from its current points (a dict; ``report`` None without a drift).

    The report is :func:`senscal.registry.store.drift_report`, the computation of ``registry due``.
    """
    out: dict[str, Any] = {"quantity": quantity, "report": None, "note": "", "status": "", "due": None}
    if len(points) < 2:
        out["note"] = "one calibration: a drift needs two"
        return out
    try:
        rep = drift_report(serial, quantity, points, tolerance=opts.tolerance, k=opts.k, as_of=as_of)
    except TooFewSamplesError:
        out["note"] = "one calibration date: a drift needs two"
        return out
    except InputError as exc:
        # Units that cannot be converted into each other, and the like: the page says why.
        out["note"] = str(exc)
        return out
    out["report"] = rep
    if rep.due is not None:
        out["due"] = rep.due_date
        out["status"] = _status(rep.due_date, as_of, opts.soon_days, rep.overdue) or "ok"
    return out


def sensor_summary(serial: str, points: list[HistoryPoint], opts: ViewOptions, as_of: datetime) -> dict[str, Any]:
    """A sensor's quantities with their drift and the sensor's earliest due date.

    ``points`` is the sensor's current history (``Registry.history(serial)``).
    """
    by_name: dict[str, list[HistoryPoint]] = {}
    for p in points:
        by_name.setdefault(p.quantity, []).append(p)
    drifts = [_quantity_drift(serial, q, pts, opts, as_of) for q, pts in by_name.items()]
    dated = [d for d in drifts if d["status"]]
    worst = max(dated, key=lambda d: (_RANK[d["status"]], -(d["due"] or as_of).timestamp()), default=None)
    return {
        "points": points, "drifts": drifts,
        "last": max((datetime.fromisoformat(p.date) for p in points), default=None),
        "status": worst["status"] if worst else "",
        "due": min((d["due"] for d in dated if d["due"] is not None), default=None),
        "due_quantity": worst["quantity"] if worst else None,
    }


def certificate_files(cal: Calibration) -> list[dict[str, Any]]:
    """The certificate files of a record that can be downloaded.

    The record's ``certificate`` is a path (``--report`` of a calibration
    command, ``registry record --certificate``) or a reference text.  A
    path to an existing PDF, HTML or XML (DCC) file is offered, and so are
    files of those types beside it with the same name (``--report C.pdf
    --dcc C.xml`` writes both; only the first is recorded).  An HTML
    certificate without a PDF beside it is also offered as PDF, printed on
    request from that HTML as ``--report C.pdf`` prints it (the same
    document).  A relative path is looked up from the folder the server
    runs in.

    Returns
    -------
    list of dict
        ``{"ext", "label", "path", "beside", "printed"}`` (``beside``: found
        next to the recorded file, not recorded itself; ``printed``: a PDF
        made from the HTML file at ``path``).
    """
    ref = (cal.certificate or "").strip()
    if not ref:
        return []
    p = Path(ref).expanduser()
    ext = p.suffix.lower()
    if ext not in CERTIFICATE_TYPES:
        return []
    out = []
    if p.is_file():
        out.append({"ext": "html" if ext == ".htm" else ext[1:], "label": CERTIFICATE_TYPES[ext][0], "path": p,
                    "beside": False, "printed": False})
    for other in (".pdf", ".html", ".xml"):
        q = p.with_suffix(other)
        if other != ext and not (ext == ".htm" and other == ".html") and q.is_file():
            out.append({"ext": other[1:], "label": CERTIFICATE_TYPES[other][0], "path": q, "beside": True,
                        "printed": False})
    html = next((f for f in out if f["ext"] == "html"), None)
    if html is not None and not any(f["ext"] == "pdf" for f in out):
        out.insert(0, {"ext": "pdf", "label": "PDF certificate", "path": html["path"], "beside": html["beside"],
                       "printed": True})
    return out


def standards_overview(reg: Registry, as_of: datetime, soon_days: int) -> list[dict[str, Any]]:
    """The current certificate of every reference standard with its due mark."""
    return [{"s": st, "status": _status(st.due, as_of, soon_days, st.overdue(as_of))} for st in reg.standards()]


def standard_detail(reg: Registry, ident: str, as_of: datetime, soon_days: int) -> dict[str, Any]:
    """Every certificate of one standard and every calibration that used one of them (``registry impact``)."""
    try:
        rep = reg.impact(ident)
    except InputError:  # unknown, or no standard ID at all (UnknownStandardError is an InputError)
        raise _NotFound(f"no reference standard {ident!r} in {reg.url}") from None
    certs = [{"s": st, "status": "" if st.superseded_by else _status(st.due, as_of, soon_days, st.overdue(as_of))}
             for st in rep.standards]
    return {"ident": ident, "certificates": certs, "impact": rep}


class _NotFound(Exception):
    """A serial, record or standard the registry does not hold (HTTP 404)."""


# --- formatting helpers for the templates ---------------------------------------

def _fmt_date(value: Any) -> str:
    """A date, or a date and time when it has one (paper certificates are dated at midnight)."""
    if value is None:
        return "-"
    if isinstance(value, str):
        try:
            value = datetime.fromisoformat(value)
        except ValueError:
            return value
    if isinstance(value, datetime):
        if (value.hour, value.minute, value.second) == (0, 0, 0):
            return value.date().isoformat()
        return value.isoformat(timespec="minutes").replace("T", " ")
    return value.isoformat() if isinstance(value, date) else str(value)


def _fmt_day(value: Any) -> str:
    """The calendar day of a date or date-time (due dates: the time of day of a fitted line means nothing)."""
    if isinstance(value, datetime):
        return value.date().isoformat()
    return _fmt_date(value)


def _value_u(value: float, U: float) -> tuple[str, str]:
    from senscal.report.certificate import value_and_u

    return value_and_u(value, U)


def _g(value: Any, digits: int = 4) -> str:
    try:
        f = float(value)
    except (TypeError, ValueError):
        return "-" if value is None else str(value)
    return f"{f:.{digits}g}" if math.isfinite(f) else "-"


def _plot_svg(points, report, title: str, label: str) -> str:
    """One quantity's history as an inline ``<svg>`` with an accessible name."""
    from markupsafe import escape

    from senscal.registry.plot import history_figure
    from senscal.report.plots import svg_inline

    with _PLOT_LOCK:
        svg = svg_inline(history_figure(points, report=report, title=title))
    # The figure is an image with a text alternative; its own title text is drawn, not read.
    return svg.replace("<svg ", f'<svg role="img" aria-label="{escape(label)}" ', 1)


# --- the application ------------------------------------------------------------

_CSP = ("default-src 'none'; style-src 'unsafe-inline'; img-src data:; form-action 'none'; "
        "frame-ancestors 'none'; base-uri 'none'")

#: Host headers a server on the loopback interface answers (IPv6 in brackets, as a browser sends it).
LOCAL_HOSTS = ("localhost", "127.0.0.1", "::1", "[::1]")


def create_app(reg: Registry, options: ViewOptions | None = None, *, trusted_hosts: Iterable[str] | None = LOCAL_HOSTS):
    """The Flask application showing ``reg`` (opened read-only: :func:`~senscal.registry.web.open_read_only`).

    Parameters
    ----------
    reg : Registry
        The registry to show; the application only reads it.
    options : ViewOptions, optional
        Tolerance and date for due dates.
    trusted_hosts : iterable of str or None
        ``Host`` headers answered (others get 400): by default the loopback
        names, so a web page elsewhere cannot reach a local server through a
        name that resolves to 127.0.0.1 (DNS rebinding).  None answers any
        host (a server bound to another interface on purpose).

    Returns
    -------
    flask.Flask
    """
    from flask import Flask, Response, render_template, request, send_file

    opts = options or ViewOptions()
    app = Flask(__name__, template_folder="templates", static_folder=None)
    # Checked here rather than by Flask's TRUSTED_HOSTS, whose matching cannot name an IPv6 address ([::1]).
    trusted = None if trusted_hosts is None else {h.strip().lower() for h in trusted_hosts}
    app.config["SENSCAL_REGISTRY"] = reg
    app.jinja_env.globals.update(fmt_date=_fmt_date, fmt_day=_fmt_day, value_u=_value_u, num=_g, url_db=reg.url, options=opts)
    app.jinja_env.filters["pretty_unit"] = _pretty_unit

    @app.before_request
    def _only_trusted_hosts():
        if trusted is None:
            return None
        host = (request.host or "").strip().lower()
        name = host[:host.find("]") + 1] if host.startswith("[") else host.partition(":")[0]
        if name not in trusted:
            return render_template("error.html", title="Bad request",
                                   message="this view answers only requests addressed to this computer"), 400
        return None

    @app.after_request
    def _headers(resp):
        resp.headers["Content-Security-Policy"] = _CSP
        resp.headers["X-Content-Type-Options"] = "nosniff"
        resp.headers["Referrer-Policy"] = "no-referrer"
        resp.headers["Cache-Control"] = "no-store"
        return resp

    @app.errorhandler(_NotFound)
    def _not_found(exc):
        return render_template("error.html", title="Not found", message=str(exc)), 404

    @app.errorhandler(404)
    def _no_page(exc):
        return render_template("error.html", title="Not found", message="no such page in the registry view"), 404

    @app.errorhandler(405)
    def _read_only(exc):
        return render_template("error.html", title="Read-only",
                               message="the registry view only reads; it has nothing that writes"), 405

    @app.errorhandler(SenscalError)
    def _senscal_error(exc):
        # A broken database (tampered value, lost server) is shown as its one line, not a traceback.
        return render_template("error.html", title="Registry error", message=str(exc)), 500

    @app.get("/")
    def index():
        as_of = opts.when()
        counts = reg.counts()
        histories = reg.histories()  # one query for every sensor
        sensors = []
        for s in reg.sensors():
            summ = sensor_summary(s.serial, histories.get(s.serial, []), opts, as_of)
            sensors.append({"sensor": s, "n": counts.get(s.serial, 0), **summ})
        return render_template("index.html", title="Sensor registry", sensors=sensors, chain=reg.verify(),
                               standards=standards_overview(reg, as_of, opts.soon_days), as_of=as_of)

    @app.get("/sensors/<path:serial>")
    def sensor(serial: str):
        as_of = opts.when()
        try:
            s = reg.sensor(serial)
        except UnknownSensorError:
            raise _NotFound(f"no sensor {serial!r} in {reg.url}") from None
        all_points = reg.history(serial, include_superseded=True)
        summ = sensor_summary(serial, [p for p in all_points if p.superseded_by is None], opts, as_of)
        records = reg.calibrations(serial, include_superseded=True)
        plots = []
        for d in summ["drifts"][:MAX_INLINE_PLOTS]:
            pts = [p for p in all_points if p.quantity == d["quantity"]]
            label = (f"Calibration history of {d['quantity']} of {serial}: {len(pts)} records with their "
                     "expanded uncertainty" + (", the fitted drift line" if d["report"] is not None else "")
                     + (" and the tolerance" if d["report"] is not None and d["report"].tolerance else ""))
            plots.append({"quantity": d["quantity"],
                          "svg": _plot_svg(pts, d["report"], f"{serial}: {d['quantity']}", label)})
        return render_template("sensor.html", title=f"Sensor {serial}", s=s, records=records, plots=plots,
                               more_plots=summ["drifts"][MAX_INLINE_PLOTS:], as_of=as_of, **summ)

    @app.get("/sensors/<path:serial>/history/<quantity>")
    def quantity_page(serial: str, quantity: str):
        as_of = opts.when()
        try:
            reg.sensor(serial)
            pts = reg.history(serial, quantity, include_superseded=True)
        except (UnknownSensorError, UnknownQuantityError) as exc:
            raise _NotFound(str(exc)) from None
        d = _quantity_drift(serial, quantity, [p for p in pts if p.superseded_by is None], opts, as_of)
        svg = _plot_svg(pts, d["report"], f"{serial}: {quantity}",
                        f"Calibration history of {quantity} of {serial}: {len(pts)} records")
        return render_template("quantity.html", title=f"{serial}: {quantity}", serial=serial, quantity=quantity,
                               d=d, svg=svg, points=pts, as_of=as_of)

    def _calibration(uid: str) -> Calibration:
        try:
            return reg.calibration(uid)
        except InputError:
            raise _NotFound(f"no calibration record {uid!r} in {reg.url}") from None

    @app.get("/calibrations/<uid>")
    def calibration(uid: str):
        cal = _calibration(uid)
        return render_template("calibration.html", title=f"Calibration {uid[:8]} of {cal.serial}", cal=cal,
                               files=certificate_files(cal),
                               result_json=json.dumps(cal.result, indent=1, ensure_ascii=False)
                               if cal.result is not None else None)

    @app.get("/calibrations/<uid>/record.json")
    def calibration_json(uid: str):
        cal = _calibration(uid)
        body = json.dumps(cal.to_dict(), indent=1, ensure_ascii=False, allow_nan=True)
        return Response(body, mimetype="application/json", headers={
            "Content-Disposition": f'attachment; filename="{_safe_name(cal.serial)}-{uid[:8]}.json"'})

    @app.get("/calibrations/<uid>/certificate.<ext>")
    def certificate(uid: str, ext: str):
        cal = _calibration(uid)
        f = next((f for f in certificate_files(cal) if f["ext"] == ext), None)
        if f is None:
            raise _NotFound(f"calibration {uid[:8]} has no {ext!r} certificate file on this computer")
        if f["printed"]:
            from senscal.report.pdf import html_to_pdf

            try:
                html = f["path"].read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise _NotFound(f"the HTML certificate {f['path']} cannot be read ({exc})") from None
            return Response(html_to_pdf(html), mimetype="application/pdf", headers={
                "Content-Disposition": f'attachment; filename="{_safe_name(f["path"].stem)}.pdf"'})
        return send_file(f["path"], mimetype=CERTIFICATE_TYPES["." + ext][1], as_attachment=True,
                         download_name=f["path"].name, max_age=0)

    @app.get("/standards/<path:ident>")
    def standard(ident: str):
        as_of = opts.when()
        return render_template("standard.html", title=f"Reference standard {ident}", as_of=as_of,
                               **standard_detail(reg, ident, as_of, opts.soon_days))

    @app.get("/chain")
    def chain():
        n, head = reg.chain_head()
        return render_template("chain.html", title="Hash chain", chain=reg.verify(), stored_head=head,
                               stored_n=n)

    return app


def _pretty_unit(unit: str) -> str:
    from senscal.report.certificate import pretty_unit

    return pretty_unit(unit or "")


def _safe_name(text: str) -> str:
    """A serial as a download file name (letters, digits, ``-._`` kept)."""
    out = "".join(ch if ch.isalnum() or ch in "-._" else "_" for ch in text)
    return out.strip("._") or "record"
