"""``senscal registry standard add|list|show|import|check`` and ``senscal registry impact``.

Reference standards live in the registry (schema 0004, :mod:`senscal.registry.standards`):
each certificate of a standard with its due date and relative standard
uncertainty, chained like the calibration records.  Calibration commands name
the standards they used with ``--standard ID`` (:mod:`senscal.cli.registry_opts`),
and ``registry impact ID`` lists every calibration that used one: what a lab
must review when a standard is found out of tolerance (ISO/IEC 17025, 7.10).
The lab profile's ``[[standards]]`` (what the certificates print) is kept in
step by ``standard import --lab-profile`` and ``standard check --lab-profile``.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli.cmd_registry import CreateOpt, registry_app
from senscal.cli.common import JsonOpt, console, err_console, print_json, table
from senscal.cli.registry_opts import DbOpt, OperatorOpt, open_named_registry
from senscal.errors import InputError

standard_app = typer.Typer(
    help="Reference standards: their certificates, due dates and uncertainties (used with --standard ID).",
    no_args_is_help=True,
)
registry_app.add_typer(standard_app, name="standard")

IdArg = Annotated[str, typer.Argument(metavar="ID", help="The lab's ID of the reference standard, e.g. REF-8305.")]
LabProfileOpt = Annotated[Path, typer.Option(
    "--lab-profile", metavar="FILE", help="Lab profile (TOML or YAML) whose [[standards]] to compare or import.")]


def _open(db: str | None, create: bool = False, *, read_only: bool = False):
    return open_named_registry(db, create=create, remedy="--create to make a new registry there",
                               read_only=read_only)


def _print_standards_head(reg) -> None:
    """The standards' chain head after a write (one stderr line, like the records' head)."""
    import sqlalchemy as sa

    from senscal.registry.db import read_connection, standards_chain

    with read_connection(reg.engine) as conn:
        row = conn.execute(sa.select(standards_chain.c.n_records, standards_chain.c.head)).first()
    if row is not None:
        err_console.print(f"standards head after {row.n_records} certificates: {row.head}")


def certificate_reference(certificate: str, dcc_hash: str | None) -> tuple[str, str | None, str]:
    """``--certificate`` and ``--dcc-hash`` as stored: (certificate id, sha256 or None, where the id came from).

    A ``--certificate`` that names an existing file is fingerprinted (SHA-256
    of its bytes); a DCC's ``uniqueIdentifier`` becomes the certificate id.  A
    ``--dcc-hash`` that disagrees with the file is refused.
    """
    from senscal.registry.standards import check_sha256

    text = str(certificate).strip()
    given = check_sha256(dcc_hash) if dcc_hash is not None else None
    path = Path(text)
    if not text or not path.is_file():
        return text, given, ""
    from senscal.registry import sha256_file

    sha = sha256_file(path)
    if given is not None and given != sha:
        raise InputError(f"--dcc-hash {given[:12]}... differs from the SHA-256 of --certificate {path} "
                         f"({sha[:12]}...); give the hash of that file, or only one of the two")
    ident = _dcc_identifier(path)
    return (ident or text), sha, str(path)


def _dcc_identifier(path: Path) -> str:
    """The ``uniqueIdentifier`` of a DCC file, '' for any other file."""
    if path.suffix.lower() != ".xml":
        return ""
    import xml.etree.ElementTree as ET

    try:
        for _, el in ET.iterparse(path, events=("end",)):
            if el.tag.endswith("}uniqueIdentifier") and (el.text or "").strip():
                return el.text.strip()
    except (ET.ParseError, OSError):
        return ""
    return ""


@standard_app.command("add")
def standard_add_cmd(
    standard: IdArg,
    certificate: Annotated[str, typer.Option(
        "--certificate", metavar="CERT", help="The standard's own calibration certificate: its number, or its file "
                                              "(a DCC's uniqueIdentifier is read and the file's SHA-256 kept).")],
    due: Annotated[str, typer.Option("--due", metavar="YYYY-MM-DD", help="When its next calibration is due.")],
    u_relative: Annotated[str, typer.Option(
        "--u-relative", metavar="U", help="Its relative standard uncertainty (k=1): 0.002 or 0.2%.")],
    name: Annotated[Optional[str], typer.Option("--name", help="Description, e.g. 'Reference accelerometer B&K 8305'.")] = None,
    serial: Annotated[Optional[str], typer.Option("--serial", help="Serial number of the standard.")] = None,
    traceability: Annotated[Optional[str], typer.Option(
        "--traceability", help="To which national standard, e.g. 'PTB, DKD-K-12345'.")] = None,
    dcc_hash: Annotated[Optional[str], typer.Option(
        "--dcc-hash", metavar="SHA256", help="SHA-256 of the standard's own DCC (when --certificate is not the file); "
                                            "the DCCs of calibrations that use it link to it.")] = None,
    renew: Annotated[bool, typer.Option(
        "--renew", help="Record the standard's next certificate after a recalibration (the previous one is "
                        "kept as history; calibrations keep the certificate they used).")] = False,
    note: Annotated[Optional[str], typer.Option("--note", help="Free text.")] = None,
    operator: OperatorOpt = None,
    db: DbOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Register a reference standard's certificate (or, with --renew, its next one); creates a --db file."""
    from senscal.registry.standards import check_ident, check_u_relative, parse_due

    # Every value is checked before the database is opened: a typo costs nothing.
    ident = check_ident(standard, "standard ID")
    parse_due(due)
    check_u_relative(u_relative)
    cert, sha, source = certificate_reference(certificate, dcc_hash)
    with _open(db, create=True) as reg:
        s = reg.add_standard(ident, certificate=cert, due=due, u_relative=u_relative, name=name, serial=serial,
                             traceability=traceability, certificate_sha256=sha, note=note, operator=operator,
                             renew=renew)
        url = reg.url
        _print_standards_head(reg)
    if json_out:
        print_json(s.to_dict())
        return
    console.print(f"{'renewed' if renew else 'registered'} standard {s.ident}: certificate {s.certificate}"
                  + (f" (from {source})" if source else "") + f", due {s.due.isoformat()}, "
                  f"u = {100 * s.u_relative:.3g} % (k=1)" + (f", SHA-256 {s.certificate_sha256[:16]}..."
                                                             if s.certificate_sha256 else "") + f" in {url}")


def _status(s, today: _dt.date) -> str:
    if s.overdue(today):
        return f"OVERDUE since {s.due.isoformat()}"
    days = (s.due - today).days
    return f"due in {days} days" if days <= 60 else ""


@standard_app.command("list")
def standard_list_cmd(
    all_certificates: Annotated[bool, typer.Option("--all", help="Include superseded certificates.")] = False,
    as_of: Annotated[Optional[str], typer.Option(
        "--as-of", metavar="YYYY-MM-DD", help="Judge 'overdue' on this date (default today).")] = None,
    db: DbOpt = None,
    create: CreateOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """The registered standards with their due dates; OVERDUE marks those past due."""
    from senscal.registry.standards import parse_due

    today = parse_due(as_of, "--as-of") if as_of is not None else _dt.date.today()
    with _open(db, create, read_only=True) as reg:
        stds = reg.standards(include_superseded=all_certificates)
        url = reg.url
    if json_out:
        print_json({"database": url, "as_of": today.isoformat(),
                    "standards": [dict(s.to_dict(), overdue=s.overdue(today)) for s in stds]})
        return
    rows = [[s.ident, s.name or "", s.certificate, s.due.isoformat(), f"{100 * s.u_relative:.3g} %",
             "superseded" if s.superseded_by else _status(s, today)] for s in stds]
    console.print(table(f"Reference standards in {url} (as of {today.isoformat()})",
                        ["ID", "name", "certificate", "due", "u (k=1)", "status"], rows))


@standard_app.command("show")
def standard_show_cmd(standard: IdArg, db: DbOpt = None, create: CreateOpt = False, json_out: JsonOpt = False) -> None:
    """Every certificate of one standard and how many calibrations used each."""
    with _open(db, create, read_only=True) as reg:
        hist = reg.standard_history(standard)
        rep = reg.impact(standard)
    used: dict[str, int] = {}
    for r in rep.rows:
        used[r.standard_certificate] = used.get(r.standard_certificate, 0) + 1
    if json_out:
        print_json({"ident": hist[-1].ident, "certificates": [dict(s.to_dict(), n_calibrations=used.get(s.certificate, 0))
                                                     for s in hist]})
        return
    today = _dt.date.today()
    cur = hist[-1]
    console.print(f"{cur.ident}: {cur.name or '-'}; serial {cur.serial or '-'}; traceability {cur.traceability or '-'}")
    rows = [[s.certificate, s.due.isoformat(), f"{100 * s.u_relative:.3g} %", (s.certificate_sha256 or "-")[:16],
             s.recorded_at.date().isoformat(), str(used.get(s.certificate, 0)),
             "superseded" if s.superseded_by else _status(s, today)] for s in hist]
    console.print(table(f"Certificates of {cur.ident}",
                        ["certificate", "due", "u (k=1)", "SHA-256", "recorded", "calibrations", "status"], rows))


# --- the lab profile kept in step ---------------------------------------------

def _profile_key(s) -> str:
    """The registry ID of a profile standard: its ``id``, else its ``serial``."""
    from senscal.registry.standards import check_ident

    key = s.id or s.serial
    if not key:
        raise InputError(f"lab profile standard {s.name!r} has neither 'id' nor 'serial'; give it the registry "
                         "ID it is registered under (id = \"REF-8305\")")
    return check_ident(key, f"lab profile standard {s.name!r} id")


def differences(profile_standards, registered) -> list[str]:
    """One sentence per difference between the profile's ``[[standards]]`` and the registry's current certificates.

    Compared: presence, certificate, due date, relative uncertainty (to 1e-12), certificate SHA-256 (when both give one).
    """
    reg = {s.ident: s for s in registered}
    out = []
    seen = set()
    for p in profile_standards:
        key = _profile_key(p)
        seen.add(key)
        r = reg.get(key)
        if r is None:
            out.append(f"{key} ({p.name}) is in the lab profile but not in the registry")
            continue
        if p.certificate != r.certificate:
            out.append(f"{key}: certificate {p.certificate or '(none)'} in the profile, {r.certificate} in the registry")
        if p.due[:10] != r.due.isoformat():
            out.append(f"{key}: due {p.due or '(none)'} in the profile, {r.due.isoformat()} in the registry")
        if p.u_relative is None or abs(p.u_relative - r.u_relative) > 1e-12:
            out.append(f"{key}: u_relative {p.u_relative} in the profile, {r.u_relative:g} in the registry")
        if p.certificate_sha256 and r.certificate_sha256 and p.certificate_sha256 != r.certificate_sha256:
            out.append(f"{key}: certificate SHA-256 {p.certificate_sha256[:12]}... in the profile, "
                       f"{r.certificate_sha256[:12]}... in the registry")
    for key in sorted(set(reg) - seen):
        out.append(f"{key} ({reg[key].name or '-'}) is in the registry but not in the lab profile")
    return out


@standard_app.command("check")
def standard_check_cmd(lab_profile: LabProfileOpt, db: DbOpt = None, create: CreateOpt = False,
                       json_out: JsonOpt = False) -> None:
    """Compare the lab profile's [[standards]] with the registry; exit 3 naming each difference."""
    from senscal.diagnostics import named
    from senscal.errors import DiagnosticError
    from senscal.report.lab import load_lab_profile

    lab, _ = load_lab_profile(lab_profile)
    with _open(db, create, read_only=True) as reg:
        diffs = differences(lab.standards, reg.standards())
        url = reg.url
    if json_out:
        print_json({"database": url, "lab_profile": str(lab_profile), "in_step": not diffs, "differences": diffs})
    elif not diffs:
        console.print(f"{lab_profile} and {url}: {len(lab.standards)} standards in step")
    for d in diffs[1:]:
        err_console.print(f"difference: {d}")
    if diffs:
        raise DiagnosticError(named("standards-out-of-step", (
            f"{len(diffs)} difference(s) between {lab_profile} and {url}, e.g. {diffs[0]}; update the profile, or "
            "'senscal registry standard import --lab-profile' / 'standard add ... --renew'")))


@standard_app.command("import")
def standard_import_cmd(
    lab_profile: LabProfileOpt,
    renew: Annotated[bool, typer.Option(
        "--renew", help="Record a profile certificate that differs from the registry's as the standard's next "
                        "certificate (without it such differences are refused).")] = False,
    db: DbOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Register the lab profile's [[standards]] (each needs id or serial, certificate, due and u_relative)."""
    from senscal.report.lab import load_lab_profile
    from senscal.registry.standards import check_u_relative, parse_due

    lab, _ = load_lab_profile(lab_profile)
    if not lab.standards:
        raise InputError(f"{lab_profile} lists no [[standards]] to import")
    todo = []
    for p in lab.standards:
        key = _profile_key(p)
        where = f"{lab_profile}: standard {key}"
        if not p.certificate:
            raise InputError(f"{where} has no 'certificate'; the registry keeps which certificate was in use")
        if not p.due:
            raise InputError(f"{where} has no 'due' date (YYYY-MM-DD)")
        if p.u_relative is None:
            raise InputError(f"{where} has no 'u_relative' (its relative standard uncertainty, k=1)")
        todo.append((key, p, parse_due(p.due, f"{where} due"), check_u_relative(p.u_relative, f"{where} u_relative")))
    added, renewed, same = [], [], []
    with _open(db, create=True) as reg:
        current = {s.ident: s for s in reg.standards()}
        for key, p, due, u in todo:
            r = current.get(key)
            if r is not None and r.certificate == p.certificate and r.due == due and abs(r.u_relative - u) <= 1e-12:
                same.append(key)
                continue
            if r is not None and not renew:
                raise InputError(f"{lab_profile}: standard {key} differs from the registry (certificate "
                                 f"{p.certificate} due {due} vs {r.certificate} due {r.due}); add --renew to record "
                                 "the profile's as its next certificate, or fix the profile")
            reg.add_standard(key, certificate=p.certificate, due=due, u_relative=u, name=p.name,
                             serial=p.serial or None, traceability=p.traceability or None,
                             certificate_sha256=p.certificate_sha256 or None, renew=r is not None)
            (renewed if r is not None else added).append(key)
        url = reg.url
        if added or renewed:
            _print_standards_head(reg)
    if json_out:
        print_json({"database": url, "added": added, "renewed": renewed, "unchanged": same})
    else:
        console.print(f"{len(added)} standards added, {len(renewed)} renewed, {len(same)} already in step in {url}")


# --- reverse traceability --------------------------------------------------------

@registry_app.command("impact")
def impact_cmd(
    standard: IdArg,
    since: Annotated[Optional[str], typer.Option(
        "--since", metavar="ISO", help="Only calibrations performed on or after this date (ISO 8601).")] = None,
    db: DbOpt = None,
    create: CreateOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Every calibration and certificate that used a reference standard: the out-of-tolerance impact report."""
    from senscal.registry import parse_date
    from senscal.registry.standards import check_ident

    ident = check_ident(standard, "standard ID")
    if since is not None:
        parse_date(since, what="--since")  # before the database is opened
    with _open(db, create, read_only=True) as reg:
        rep = reg.impact(ident, since=since)
        url = reg.url
    if json_out:
        print_json(dict(rep.to_dict(), database=url))
        return
    rows = [[r.performed_at[:10], r.serial, r.job, r.calibration[:8], r.certificate or "-", r.standard_certificate,
             ("OVERDUE" if r.overdue else "") + (" superseded" if r.superseded_by else "")] for r in rep.rows]
    console.print(table(f"Calibrations that used {rep.ident}" + (f" since {since}" if since else "") + f" ({url})",
                        ["date", "sensor", "job", "record", "certificate issued", "standard's certificate", "note"],
                        rows))
    console.print(f"{_count(rep.n_calibrations, 'calibration')} of {_count(rep.n_sensors, 'sensor')}, "
                  f"{rep.n_certificates} with a certificate; {rep.n_overdue} made while the standard was overdue")


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")
