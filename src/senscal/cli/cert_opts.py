"""``--report FILE.pdf|.html --dcc FILE.xml --lab FILE --run FILE --customer ...`` for calibration commands.

A command that issues a certificate adds the option aliases below to its
signature and calls :func:`certify` once with its result; ``certify``
returns the certificate's named warnings (``certificate-draft``,
``budget-zero-component``, ``u-below-reference``) for the command to add to
its own before :func:`~senscal.cli.common.emit_warnings`::

    from senscal.cli.cert_opts import (CertIdOpt, CustomerOpt, DccOpt, EnvOpt, ItemOpt, LabOpt, LocationOpt,
                                       ManufacturerOpt, ModelOpt, ReportOpt, RunFileOpt, SensorIdOpt, certify)

    @app.command("response")
    def response_cmd(..., report: ReportOpt = None, dcc: DccOpt = None, lab: LabOpt = None,
                     run_file: RunFileOpt = None, customer: CustomerOpt = None, item: ItemOpt = None,
                     manufacturer: ManufacturerOpt = None, model: ModelOpt = None, sensor_id: SensorIdOpt = None,
                     location: LocationOpt = None, certificate_id: CertIdOpt = None,
                     calibration_date: CalDateOpt = None, env: EnvOpt = None, sensor: SensorOpt = None,
                     ...) -> None:
        ...
        cert_warns = certify("response", resp, report=report, dcc=dcc, unit=unit, method=meth, conditions=cond,
                             files=files, warnings=result.warnings, **cert_fields(locals()))
        emit_warnings([*result.warnings, *cert_warns], strict)

Where the fields come from (later wins): the lab profile's ``[run]`` table
(``--lab FILE``, default ``$SENSCAL_LAB`` or ``~/.config/senscal/lab.toml``),
then the run file (``--run FILE``: a ``[run]`` table or top-level fields, for
what has no option of its own: customer address, deviations, statement of
conformity and decision rule, approver, issue date, remarks), then the
options.  The calibration date is ``--calibration-date``, else the registry's ``--date`` (with ``--save``).
The serial number is ``--serial`` (alias ``--sensor-id``), else the registry's
``--sensor``.  Nothing happens without ``--report`` or ``--dcc``.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import replace
from pathlib import Path
from typing import Any, List, Mapping, Optional, Sequence

import typer
from typing_extensions import Annotated

from senscal.cli.common import err_console
from senscal.errors import InputError

__all__ = ["ReportOpt", "DccOpt", "LabOpt", "RunFileOpt", "CustomerOpt", "ItemOpt", "ManufacturerOpt", "ModelOpt",
           "SensorIdOpt", "LocationOpt", "CertIdOpt", "CalDateOpt", "EnvOpt", "ConformityOpt", "DecisionRuleOpt",
           "SignKeyOpt", "SignCertOpt",
           "certificate_info", "cert_fields", "certify", "check_conformity", "decide_conformity"]

_PANEL = "Certificate"

ReportOpt = Annotated[Optional[Path], typer.Option(
    "--report", metavar="FILE.pdf|FILE.html", help="Write the calibration certificate: PDF (A4) for .pdf, HTML for .html.",
    rich_help_panel=_PANEL)]
DccOpt = Annotated[Optional[Path], typer.Option(
    "--dcc", metavar="FILE.xml", help="Write the Digital Calibration Certificate (PTB DCC XML, validated against its "
                                      "schema).", rich_help_panel=_PANEL)]
LabOpt = Annotated[Optional[Path], typer.Option(
    "--lab", metavar="FILE", help="Lab profile, TOML or YAML (default: $SENSCAL_LAB, else lab.toml in "
                                  "~/.config/senscal).", rich_help_panel=_PANEL)]
RunFileOpt = Annotated[Optional[Path], typer.Option(
    "--run", metavar="FILE", help="Certificate fields of this calibration: TOML or YAML, a 'run' table or top-level fields; "
                                 "options win.",
    rich_help_panel=_PANEL)]
CustomerOpt = Annotated[Optional[str], typer.Option("--customer", help="Customer name (certificate).",
                                                    rich_help_panel=_PANEL)]
ItemOpt = Annotated[Optional[str], typer.Option(
    "--item", help="Description of the item calibrated, e.g. 'piezoelectric accelerometer'.", rich_help_panel=_PANEL)]
ManufacturerOpt = Annotated[Optional[str], typer.Option("--manufacturer", help="Manufacturer of the item.",
                                                        rich_help_panel=_PANEL)]
ModelOpt = Annotated[Optional[str], typer.Option("--model", help="Model (type) of the item.", rich_help_panel=_PANEL)]
SensorIdOpt = Annotated[Optional[str], typer.Option("--serial", "--sensor-id", help="Serial number of the item (default: the registry's --sensor).",
                                                    rich_help_panel=_PANEL)]
LocationOpt = Annotated[Optional[str], typer.Option(
    "--location", help="Where the calibration was done (the lab, or the customer's site).", rich_help_panel=_PANEL)]
CertIdOpt = Annotated[Optional[str], typer.Option(
    "--certificate-id", help="Certificate number (default SC-YYYYMMDD-<digest of result and item>).",
    rich_help_panel=_PANEL)]
CalDateOpt = Annotated[Optional[str], typer.Option(
    "--calibration-date", metavar="YYYY-MM-DD", help="Date of the calibration (default: the registry's --date with "
                                                     "--save).", rich_help_panel=_PANEL)]
EnvOpt = Annotated[Optional[List[str]], typer.Option(
    "--env", metavar="NAME=VALUE+-U UNIT", help="Environmental condition with its standard uncertainty (repeatable), "
                                                "e.g. 'temperature=23.1+-0.5 degC'.", rich_help_panel=_PANEL)]
ConformityOpt = Annotated[Optional[str], typer.Option(
    "--conformity", metavar="NAME=VALUE+-TOL", help="Specification for a statement of conformity of every point: "
    "'sensitivity=0.05+-2%', 'sensitivity=50 mV/(m/s^2)+-1 mV/(m/s^2)', 'sensitivity=0.049..0.051', "
    "'phase_delay_deg<=5'. Adds conformity and probability_false_accept per point (JSON, certificate, DCC).",
    rich_help_panel=_PANEL)]
DecisionRuleOpt = Annotated[Optional[str], typer.Option(
    "--decision-rule", metavar="simple|guard-band|non-binary", help="ILAC-G8:09/2019 decision rule of --conformity: "
    "simple (w = 0, the default), guard-band (w = U), non-binary (pass, conditional pass, conditional fail, fail).",
    rich_help_panel=_PANEL)]
SignKeyOpt = Annotated[Optional[Path], typer.Option(
    "--sign-key", metavar="KEY.pem", help="Sign the DCC (XAdES-B-B enveloped XML signature) with this private key "
    "(PEM, RSA or EC; an encrypted key's password in $SENSCAL_SIGN_KEY_PASSWORD). Needs --sign-cert and --dcc.",
    rich_help_panel=_PANEL)]
SignCertOpt = Annotated[Optional[Path], typer.Option(
    "--sign-cert", metavar="CERT.pem", help="The signer's X.509 certificate (PEM), embedded in the DCC's signature.",
    rich_help_panel=_PANEL)]


def _date_part(text: str | None) -> str:
    """The date of an ISO 8601 date or date-time (the registry's ``--date``)."""
    if not text:
        return ""
    try:
        return _dt.datetime.fromisoformat(text).date().isoformat()
    except ValueError:
        raise InputError(f"calibration date {text!r} is not an ISO 8601 date (YYYY-MM-DD[THH:MM])") from None


def certificate_info(*, lab: Path | None = None, run_file: Path | None = None, customer: str | None = None,
                     item: str | None = None, manufacturer: str | None = None, model: str | None = None,
                     serial: str | None = None, location: str | None = None, certificate_id: str | None = None,
                     env: Sequence[str] | None = None, calibration_date: str | None = None,
                     conformity: str | None = None, decision_rule: str | None = None, standards: Any = None):
    """The :class:`~senscal.report.lab.CertificateInfo` from the profile, the run file and the options.

    ``standards`` (:class:`~senscal.cli.registry_opts.UsedStandards`, from ``--standard``) replaces the
    profile's reference standards by the registry's ones the calibration used.

    Raises
    ------
    InputError
        An unreadable or invalid profile or run file, a malformed ``--env``.
    """
    from senscal.report.lab import (CertificateInfo, LabProfile, RunInfo, default_lab_path, load_lab_profile,
                                    load_run_file, merge_run, parse_condition)

    path = lab if lab is not None else default_lab_path()
    profile, run = load_lab_profile(path) if path is not None else (LabProfile(), RunInfo())
    if run_file is not None:
        given = load_run_file(run_file)
        run = merge_run(run, **{k: getattr(given, k) for k in given.__dataclass_fields__})
    conds = tuple(parse_condition(e) for e in env or ())
    run = merge_run(run, customer=customer, item=item, manufacturer=manufacturer, model=model, serial=serial,
                    location=location, certificate_id=certificate_id, calibration_date=_date_part(calibration_date),
                    conditions=conds, conformity=conformity, decision_rule=decision_rule)
    if standards is not None:
        profile = replace(profile, standards=standards.lab_standards(profile.standards))
    return CertificateInfo(profile, run)


def cert_fields(params: Mapping[str, Any]) -> dict[str, Any]:
    """The certificate options among a command's parameters (``locals()``), as :func:`certify` takes them."""
    out = {k: params.get(k) for k in ("lab", "run_file", "customer", "item", "manufacturer", "model", "location",
                                      "certificate_id", "env")}
    out["serial"] = params.get("sensor_id") or params.get("sensor")
    out["calibration_date"] = params.get("calibration_date") or params.get("date")
    out["conformity"] = params.get("conformity")
    out["decision_rule"] = params.get("decision_rule")
    out["sign_key"] = params.get("sign_key")
    out["sign_cert"] = params.get("sign_cert")
    # --standard IDs looked up in the registry (senscal.cli.registry_opts.use_standards), when the command has them
    out["standards"] = params.get("used_standards")
    return out


def _signing_material(key: Path | None, cert: Path | None, dcc: Path | None) -> tuple[bytes, bytes, bytes | None] | None:
    """The PEM bytes of ``--sign-key``/``--sign-cert`` (checked to belong together), None without them."""
    import os

    if key is None and cert is None:
        return None
    if key is None or cert is None:
        raise InputError("--sign-key and --sign-cert go together: give the signer's private key and its certificate")
    if dcc is None:
        raise InputError("--sign-key signs the DCC; add --dcc FILE.xml")
    data = []
    for path, opt in ((key, "--sign-key"), (cert, "--sign-cert")):
        try:
            data.append(Path(path).read_bytes())
        except OSError as exc:
            raise InputError(f"{opt} {path}: cannot read it ({exc.strerror or exc}); give a readable PEM file") from None
    pw = os.environ.get("SENSCAL_SIGN_KEY_PASSWORD")
    password = pw.encode() if pw else None
    from senscal.report.signing import load_signing_material

    load_signing_material(data[0], data[1], password=password)  # refuse a bad pair before anything is written
    return data[0], data[1], password


def check_conformity(conformity: str | None, decision_rule: str | None) -> None:
    """Refuse a bad ``--conformity``/``--decision-rule`` before the job runs (the same checks as
    :func:`decide_conformity`, without a result)."""
    from senscal.report.conformity import RULES, parse_specification

    if conformity is None:
        if decision_rule is not None:
            raise InputError("--decision-rule needs --conformity NAME=VALUE+-TOL (the specification to decide on)")
        return
    if decision_rule is not None and decision_rule.strip().lower() not in RULES:
        raise InputError(f"--decision-rule {decision_rule!r} is not known; use one of {', '.join(RULES)}")
    parse_specification(conformity)


def decide_conformity(doc: dict | None, conformity: str | None, decision_rule: str | None) -> tuple[str | None, str | None]:
    """``--conformity``/``--decision-rule`` decided on the command's JSON document (per point, in place).

    Returns the statement and the decision rule for the certificate, (None, None) without ``--conformity``.

    Raises
    ------
    InputError
        ``--decision-rule`` without ``--conformity``, an unknown rule, a malformed specification, a quantity
        the result does not have.
    """
    from senscal.report.conformity import RULES, apply_to_document, parse_specification

    if conformity is None:
        if decision_rule is not None:
            raise InputError("--decision-rule needs --conformity NAME=VALUE+-TOL (the specification to decide on)")
        return None, None
    rule = (decision_rule or "simple").strip().lower()
    if rule not in RULES:
        raise InputError(f"--decision-rule {decision_rule!r} is not known; use one of {', '.join(RULES)}")
    spec = parse_specification(conformity)
    if doc is None:
        raise InputError("--conformity: this command has no per-point result to decide on")
    return apply_to_document(doc, spec, rule)


def certify(kind: str, result: Any, *, report: Path | None, dcc: Path | None, unit: str, method: str,
            conditions: Mapping[str, Any], files: Sequence[str], warnings: Sequence[str] = (),
            doc: dict | None = None, **fields: Any) -> list[str]:
    """Write the certificate (``--report``) and the DCC (``--dcc``) of one result; return their warnings.

    Parameters
    ----------
    kind : str
        ``"response"``, ``"velocity"`` or ``"linearity"``.
    result : object
        The engine result the certificate reports (FrequencyResponse, VelocityCalibration, AmplitudeLinearity).
    report, dcc : Path or None
        Where to write them; nothing is done when both are None.
    unit, method : str
        Sensitivity unit; method statement.
    conditions : mapping
        Settings of the calibration shown on the certificate.
    files : sequence of str
        Records used.
    warnings : sequence of str
        The command's named warnings (printed on the certificate with the certificate's own).
    doc : dict, optional
        The command's JSON document: with ``conformity`` in ``fields`` each point gets its ``conformity`` and
        ``probability_false_accept`` (:func:`decide_conformity`), also without ``--report``/``--dcc``.
    **fields
        The certificate options: ``lab``, ``run_file``, ``customer``, ``item``, ``manufacturer``, ``model``,
        ``serial``, ``location``, ``certificate_id``, ``env``, ``calibration_date``, ``conformity`` (a
        specification), ``decision_rule`` (see :func:`certificate_info`); ``sign_key``, ``sign_cert`` (PEM files:
        the DCC is signed, :func:`senscal.report.signing.sign_dcc`); ``standards``
        (:class:`~senscal.cli.registry_opts.UsedStandards` from ``--standard``: the certificate lists those
        registry standards instead of the profile's, and prints their ``standard-overdue`` warnings, which the
        command emits itself).

    Returns
    -------
    list of str
        ``conformity-no-acceptance-interval`` (with ``--conformity``: U >= half the tolerance with a guard band),
        ``certificate-draft`` (a required field is missing: DRAFT on every page), ``budget-zero-component``,
        ``u-below-reference``; the last three only when something was written.
    """
    fields["conformity"], fields["decision_rule"] = decide_conformity(doc, fields.get("conformity"),
                                                                       fields.get("decision_rule"))
    signing = _signing_material(fields.pop("sign_key", None), fields.pop("sign_cert", None), dcc)
    used = fields.get("standards")
    conf_warns = _conformity_warnings(doc)
    if report is None and dcc is None:
        return conf_warns
    from senscal.cli.common import window_text

    if window_text() is not None:
        conditions = {**conditions, "record window (--start/--stop)": window_text()}  # which part was used
    from senscal.io.guard import check_output, write_bytes
    from senscal.report.certificate import REPORT_SUFFIXES, certificate_bytes, certificate_id, certificate_warnings

    # Refuse a bad path before anything is written: a PDF without its DCC (or the reverse) is half an issue.
    if report is not None:
        report = check_output(report, suffixes=REPORT_SUFFIXES, what="--report")
    if dcc is not None:
        dcc = check_output(dcc, suffixes=(".xml",), what="--dcc")
    info = certificate_info(**fields)  # with --standard: the registry's standards (certificate, due, u, SHA-256)
    if used is not None:
        warnings = [*warnings, *used.warnings]
    now = _dt.datetime.now(_dt.timezone.utc)
    # The PDF/HTML and the DCC carry the same id and issue date.
    run = replace(info.run, issue_date=info.run.issue_date or now.date().isoformat())
    info = replace(info, run=replace(run, certificate_id=certificate_id(kind, result, replace(info, run=run), now)))
    warns = list(certificate_warnings(kind, result, info))
    cert_day = info.run.calibration_date.split("/")[-1][:10]
    if used is not None and cert_day in ("", used.on.isoformat()):
        # Judged on the same day, an overdue registry standard is named standard-overdue (in `warnings`), not twice;
        # a run file's other calibration date keeps the certificate's own reference-standard-due.
        warns = [w for w in warns if not w.startswith("reference-standard-due:")]
    shown = [*warnings, *warns]
    # Both are built (and checked) before either is written.
    data = None if report is None else certificate_bytes(report.suffix, kind, result, info=info, unit=unit,
                                                         method=method, conditions=conditions, files=files,
                                                         warnings=shown)
    if dcc is not None:
        _write_dcc(dcc, kind, result, info, unit=unit, method=method, files=files, warnings=shown, signing=signing)
        err_console.print(f"DCC {info.run.certificate_id} {'signed and ' if signing else ''}written to {dcc}")  # stdout stays clean for --json
    if data is not None:
        write_bytes(report, data, what="report")
    return [*conf_warns, *warns]


def _conformity_warnings(doc: dict | None) -> list[str]:
    """``conformity-no-acceptance-interval`` when a guard band w = U left some point nothing to pass."""
    conf = (doc or {}).get("conformity") or {}
    n = conf.get("no_acceptance_interval_points") or 0
    if not n:
        return []
    return [f"conformity-no-acceptance-interval: at {n} point(s) U is at least half the tolerance interval of "
            f"{conf.get('quantity')}, so the {conf.get('decision_rule')} rule cannot pass them whatever the value; "
            "a smaller uncertainty or a wider tolerance makes the decision meaningful"]


def _write_dcc(path: Path, kind: str, result: Any, info: Any, *, signing: tuple | None = None, **kw: Any) -> None:
    try:
        from senscal.report.dcc import dcc_xml, write_dcc
    except ModuleNotFoundError as exc:
        if exc.name != "senscal.report.dcc":
            raise
        raise InputError("--dcc: this senscal has no DCC writer (senscal.report.dcc); write --report only") from None
    if signing is None:
        write_dcc(path, kind, result, info, **kw)
        return
    from senscal.io.guard import write_bytes
    from senscal.report.signing import sign_dcc

    key, cert, password = signing
    write_bytes(path, sign_dcc(dcc_xml(kind, result, info, **kw), key, cert, password=password), what="DCC")
