"""The laboratory profile and the per-run certificate fields (ISO/IEC 17025:2017, 7.8).

A lab writes its profile once (``lab.toml`` or ``lab.yaml``): name,
address, accreditation, logo, approvers, reference standards, procedures.
Each calibration run adds its own fields (customer, item, dates, location,
environmental conditions ...) on the command line or in a ``[run]`` table of
the same file. Missing required fields never print as "not stated": the
certificate is marked DRAFT and :func:`missing_fields` names them, which the
command turns into the ``certificate-draft`` warning (``--strict`` exits 3).

Contract shared by the HTML/PDF certificate and the DCC XML writer: both take
a :class:`CertificateInfo` (lab + run) and never read files themselves.

References
----------
.. [1] ISO/IEC 17025:2017, 7.8.2 (common requirements for reports) and
   7.8.4 (specific requirements for calibration certificates).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Sequence, Any, Mapping

from senscal._result import ResultMixin
from senscal.errors import InputError

__all__ = ["Person", "Standard", "Condition", "LabProfile", "RunInfo", "CertificateInfo", "load_lab_profile",
           "load_run_file", "parse_condition", "run_info_from", "merge_run", "missing_fields", "default_lab_path",
           "REQUIRED_LAB", "REQUIRED_RUN", "signing_approvers", "example_info"]


@dataclass(frozen=True)
class Person(ResultMixin):
    """An approver: who authorises the certificate (7.8.2.1 o)."""

    name: str
    role: str = ""


@dataclass(frozen=True)
class Standard(ResultMixin):
    """A reference standard used in the calibration, with its own traceability (7.8.4.1 c, 6.5).

    Attributes
    ----------
    name : str
        e.g. "Reference accelerometer B&K 8305".
    serial : str
    certificate : str
        Id of the standard's own calibration certificate.
    traceability : str
        To which national standard / NMI, e.g. "PTB, DKD-K-12345".
    due : str
        Date its calibration is due (ISO 8601), may be empty.
    u_relative : float or None
        Its own relative standard uncertainty (k=1) where it applies, used by
        the budget sanity check (a result cannot be better than its reference).
    id : str
        The lab's ID of the standard in the registry (``senscal registry
        standard add ID``), may be empty; ``senscal registry standard check
        --lab-profile`` compares the profile with the registry by it (else by
        ``serial``).
    certificate_sha256 : str
        SHA-256 of the standard's own certificate file (its DCC), may be empty:
        the DCC links to it (``hashType``).
    """

    name: str
    serial: str = ""
    certificate: str = ""
    traceability: str = ""
    due: str = ""
    u_relative: float | None = None
    id: str = ""
    certificate_sha256: str = ""

    @property
    def traceable(self) -> bool:
        """Whether this standard carries a traceability statement (not empty, not "none..." / "not ...")."""
        text = self.traceability.strip().lower()
        return bool(text) and not (text.startswith("none") or text.startswith("not ") or text.startswith("no "))

    def due_status(self, on: str) -> str:
        """``""`` when in date on ``on`` (ISO date), ``"missing"`` without a due date, ``"overdue"`` past it."""
        if not self.due:
            return "missing"
        first = (on or "").split("/")[-1][:10]
        return "overdue" if first and self.due[:10] < first else ""


def traceability_claim(standards: Sequence["Standard"]) -> tuple[bool, str]:
    """Whether the standards support an SI traceability claim, and the sentence a certificate prints.

    The claim follows from the standards: it is made only when at least
    one standard is listed and every one of them carries a traceability
    statement; otherwise the sentence names the standards without one.
    """
    if not standards:
        return False, ""
    lacking = [s for s in standards if not s.traceable]
    if not lacking:
        return True, ("The measurements are metrologically traceable to the International System of Units (SI) "
                      "through the reference standards above, whose own calibration certificates are listed.")
    names = ", ".join(f"'{s.name}'" + (f" ({s.traceability})" if s.traceability else "") for s in lacking)
    return False, (f"No metrological traceability to the SI is claimed: no traceability is stated for the "
                   f"reference standard(s) {names}.")


@dataclass(frozen=True)
class Condition(ResultMixin):
    """An environmental condition with its uncertainty (7.8.4.1 a), e.g. temperature 23.1 +- 0.5 degC.

    Attributes
    ----------
    name : str
        e.g. "temperature".
    value : float
        In ``unit``.
    uncertainty : float or None
        Standard uncertainty (k=1) in ``unit``, as every uncertainty in
        senscal; certificates print the expanded ``U = 2u``.
    unit : str
        e.g. "degC", "%RH".
    """

    name: str
    value: float
    uncertainty: float | None = None
    unit: str = ""


@dataclass(frozen=True)
class LabProfile(ResultMixin):
    """What a laboratory states on every certificate (7.8.2.1 a, o; 7.8.4)."""

    name: str = ""
    address: str = ""
    accreditation: str = ""          # accreditation body and number, e.g. "DAkkS D-K-12345-01-00"
    logo: str = ""                   # path to an image file, resolved against the profile's folder
    approvers: tuple[Person, ...] = ()
    standards: tuple[Standard, ...] = ()
    procedure: str = ""              # procedure id, e.g. "QP-VIB-07 rev 3"
    phone: str = ""
    email: str = ""
    country: str = ""                # ISO 3166-1 alpha-2 code of the lab, e.g. "DE" (the DCC needs it)
    source: str = ""                 # the profile file this came from (for messages)


@dataclass(frozen=True)
class RunInfo(ResultMixin):
    """The fields of one calibration (7.8.2.1 b-n, 7.8.4.1).

    Dates are ISO 8601 strings; ``issue_date`` defaults to the day the
    certificate is written.
    """

    certificate_id: str = ""
    customer: str = ""
    customer_address: str = ""
    customer_email: str = ""         # the DCC schema requires a customer e-mail
    item: str = ""                   # description, e.g. "piezoelectric accelerometer"
    manufacturer: str = ""
    model: str = ""
    serial: str = ""
    calibration_date: str = ""       # YYYY-MM-DD, or YYYY-MM-DD/YYYY-MM-DD for a calibration over several days
    receipt_date: str = ""           # when the item was received (DCC receiptDate), may be empty
    issue_date: str = ""
    location: str = ""               # where the calibration was done (lab, or the customer's site)
    conditions: tuple[Condition, ...] = ()
    deviations: str = ""             # deviations from, additions to or exclusions from the method
    conformity: str = ""             # statement of conformity, when the customer asked for one
    decision_rule: str = ""          # the decision rule used for the statement of conformity
    remarks: str = ""
    approver: str = ""               # who authorises this certificate: one of the lab's approvers (default: all listed)


@dataclass(frozen=True)
class CertificateInfo(ResultMixin):
    """Lab profile plus run fields: everything a certificate states besides the results."""

    lab: LabProfile = field(default_factory=LabProfile)
    run: RunInfo = field(default_factory=RunInfo)

    @property
    def draft(self) -> bool:
        """True when a required field is missing (the certificate says DRAFT on every page)."""
        return bool(missing_fields(self))


# Fields 17025 requires of a calibration certificate; missing -> DRAFT.
REQUIRED_LAB = ("name", "address", "approvers", "standards")
REQUIRED_RUN = ("customer", "item", "serial", "calibration_date", "location", "conditions")


def missing_fields(info: CertificateInfo) -> list[str]:
    """Required fields that are empty, as ``lab.name`` / ``run.customer`` / ``run.conformity.decision_rule``."""
    out = [f"lab.{n}" for n in REQUIRED_LAB if not getattr(info.lab, n)]
    out += [f"run.{n}" for n in REQUIRED_RUN if not getattr(info.run, n)]
    if info.run.conformity and not info.run.decision_rule:
        out.append("run.decision_rule")
    return out


def default_lab_path() -> Path | None:
    """``$SENSCAL_LAB`` if set, else ``lab.toml``/``lab.yaml`` in the user config folder, if it exists."""
    env = os.environ.get("SENSCAL_LAB")
    if env:
        return Path(env)
    base = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config") / "senscal"
    for name in ("lab.toml", "lab.yaml", "lab.yml"):
        if (base / name).is_file():
            return base / name
    return None


def _text(doc: Mapping[str, Any], key: str, where: str) -> str:
    v = doc.get(key, "")
    if v is None:
        return ""
    if isinstance(v, (dict, list)):
        raise InputError(f"{where}: '{key}' must be text, got a {type(v).__name__}")
    return str(v).strip()


def _known(doc: Mapping[str, Any], allowed: set[str], where: str) -> None:
    unknown = sorted(set(doc) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown field(s) {', '.join(map(repr, unknown))}; known: {', '.join(sorted(allowed))}")


def _float_or_none(v: Any, what: str) -> float | None:
    if v is None or v == "":
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number, got {v!r}") from None


def _list(doc: Mapping[str, Any], key: str, where: str, what: str) -> list:
    v = doc.get(key) or []
    if not isinstance(v, list):
        raise InputError(f"{where}: '{key}' must be {what}, got a {type(v).__name__}")
    return v


def _iso_date(text: str, what: str) -> None:
    import datetime as _dt

    try:
        _dt.date.fromisoformat(text)
    except ValueError:
        raise InputError(f"{what} {text!r} is not a calendar date; write it as YYYY-MM-DD") from None


def _condition_ok(value: float | None, u: float | None) -> bool:
    """A certificate states a condition with a finite value and, if any, a finite uncertainty u >= 0."""
    return value is not None and math.isfinite(value) and (u is None or (u >= 0 and math.isfinite(u)))


def _conditions(items: Any, where: str) -> tuple[Condition, ...]:
    if items in (None, ""):
        return ()
    if isinstance(items, Mapping):  # {"temperature": {"value": 23.1, "u": 0.5, "unit": "degC"}} or {"temperature": 23.1}
        items = [{"name": k, **(v if isinstance(v, Mapping) else {"value": v})} for k, v in items.items()]
    if not isinstance(items, list):
        raise InputError(f"{where}: 'conditions' must be a table or a list of tables")
    out = []
    for c in items:
        if not isinstance(c, Mapping) or "name" not in c or "value" not in c:
            raise InputError(f"{where}: each condition needs 'name' and 'value' (and optional 'u', 'unit')")
        _known(c, {"name", "value", "u", "uncertainty", "unit"}, f"{where} condition {c.get('name')!r}")
        value = _float_or_none(c["value"], f"{where}: condition {c['name']!r} value")
        u = _float_or_none(c.get("u", c.get("uncertainty")), f"{where}: condition {c['name']!r} u")
        if not _condition_ok(value, u):  # the same rule as --env
            raise InputError(f"{where}: condition {c['name']!r} needs a finite value and a finite uncertainty u >= 0, "
                             f"got value {c['value']!r}, u {c.get('u', c.get('uncertainty'))!r}")
        out.append(Condition(str(c["name"]), value, u, str(c.get("unit", ""))))
    return tuple(out)


def _lab_from(doc: Mapping[str, Any], where: str, source: str) -> LabProfile:
    allowed = {f.name for f in fields(LabProfile)} - {"source"}
    _known(doc, allowed, where)
    approvers = []
    # A bare string would be iterated letter by letter (one approver per character).
    for a in _list(doc, "approvers", where, "a list of names or of tables with 'name' (and 'role')"):
        if isinstance(a, str):
            approvers.append(Person(a.strip()))
        elif isinstance(a, Mapping) and "name" in a:
            _known(a, {"name", "role"}, f"{where} approver")
            approvers.append(Person(str(a["name"]).strip(), str(a.get("role", "")).strip()))
        else:
            raise InputError(f"{where}: each approver is a name or a table with 'name' (and 'role')")
    standards = []
    for s in _list(doc, "standards", where, "a list of tables ([[standards]] in TOML), each with at least 'name'"):
        if not isinstance(s, Mapping) or "name" not in s:
            raise InputError(f"{where}: each reference standard is a table with at least 'name'")
        allowed_s = {f.name for f in fields(Standard)}
        _known(s, allowed_s, f"{where} standard {s.get('name')!r}")
        std = Standard(**{k: (str(v).strip() if k != "u_relative" else
                              _float_or_none(v, f"{where}: standard {s['name']!r} u_relative"))
                          for k, v in s.items()})
        if std.u_relative is not None and not (math.isfinite(std.u_relative) and std.u_relative >= 0):
            raise InputError(f"{where}: standard {s['name']!r} u_relative must be a finite number >= 0 (its relative "
                             f"standard uncertainty, k=1), got {s['u_relative']!r}")
        if std.due:
            _iso_date(std.due, f"{where}: standard {s['name']!r} due")
        if std.certificate_sha256:
            import re

            sha = std.certificate_sha256.lower().removeprefix("sha256:")
            if not re.fullmatch(r"[0-9a-f]{64}", sha):
                raise InputError(f"{where}: standard {s['name']!r} certificate_sha256 must be the SHA-256 of its own "
                                 f"certificate file (64 hex digits), got {std.certificate_sha256!r}")
            std = replace(std, certificate_sha256=sha)
        standards.append(std)
    logo = _text(doc, "logo", where)
    if logo and source and not Path(logo).is_absolute():
        logo = str(Path(source).parent / logo)
    return LabProfile(name=_text(doc, "name", where), address=_text(doc, "address", where),
                      accreditation=_text(doc, "accreditation", where), logo=logo, approvers=tuple(approvers),
                      standards=tuple(standards), procedure=_text(doc, "procedure", where),
                      phone=_text(doc, "phone", where), email=_text(doc, "email", where),
                      country=_text(doc, "country", where), source=source)


def run_info_from(doc: Mapping[str, Any] | None, where: str = "run") -> RunInfo:
    """A :class:`RunInfo` from a mapping (the ``[run]`` table, or CLI options collected into one)."""
    doc = dict(doc or {})
    allowed = {f.name for f in fields(RunInfo)}
    _known(doc, allowed, where)
    conds = _conditions(doc.pop("conditions", None), where)
    return RunInfo(**{k: _text(doc, k, where) for k in doc}, conditions=conds)


def _read_doc(p: Path, what: str) -> Mapping[str, Any]:
    """A TOML or YAML file (by suffix) as a mapping; one-line errors naming the file."""
    suffix = p.suffix.lower()
    if suffix == ".toml":
        import tomllib

        from senscal.io.sidefiles import read_text

        try:
            doc = tomllib.loads(read_text(p, what))
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"{what} {p} is not valid TOML ({exc}); fix the file") from None
    elif suffix in (".yaml", ".yml"):
        from senscal.io.sidefiles import read_yaml

        doc = read_yaml(p, what)
    else:
        raise InputError(f"{what} {p}: use a .toml or .yaml file")
    if not isinstance(doc, Mapping):
        raise InputError(f"{what} {p} must hold a table of fields")
    return doc


def load_lab_profile(path: str | os.PathLike) -> tuple[LabProfile, RunInfo]:
    """Read a lab profile (TOML or YAML by suffix): the lab, and the ``[run]`` defaults it may carry.

    Raises
    ------
    InputError
        Unreadable file, bad syntax, unknown field or wrong type: one line naming the file and the field.
    """
    p = Path(path)
    where = str(p)
    doc = _read_doc(p, "lab profile")
    run = doc.get("run") or {}
    lab_doc = doc.get("lab", {k: v for k, v in doc.items() if k != "run"})
    if not isinstance(lab_doc, Mapping) or not isinstance(run, Mapping):
        raise InputError(f"lab profile {p}: 'lab' and 'run' must be tables")
    return _lab_from(lab_doc, where, str(p)), run_info_from(run, f"{where} [run]")


def merge_run(base: RunInfo, **given: Any) -> RunInfo:
    """``base`` with the non-empty values in ``given`` (command-line options win over the profile)."""
    vals = {k: v for k, v in given.items() if v not in (None, "", ())}
    return replace(base, **vals)


def parse_condition(text: str, where: str = "--env") -> Condition:
    """An environmental condition from ``NAME=VALUE[+-U] [UNIT]``, e.g. ``temperature=23.1+-0.5 degC``.

    ``U`` after ``+-`` (or ``±``) is the standard uncertainty (k=1) in the same unit.

    Raises
    ------
    InputError
        Not of that form, or a value that is not a number.
    """
    import re

    name, sep, rest = str(text).partition("=")
    num = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
    m = re.fullmatch(rf"\s*({num})\s*(?:(?:\+/?-|±)\s*({num}))?\s*(.*?)\s*", rest)
    if not sep or not name.strip() or m is None or m.group(3).startswith(("+", "±")):
        raise InputError(f"{where} must look like NAME=VALUE+-U UNIT (U the standard uncertainty), "
                         f"e.g. 'temperature=23.1+-0.5 degC'; got {text!r}")
    value = _float_or_none(m.group(1), f"{where} {name.strip()!r} value")
    u = _float_or_none(m.group(2), f"{where} {name.strip()!r} uncertainty")
    if not _condition_ok(value, u):
        raise InputError(f"{where} {name.strip()!r}: give a value and a non-negative uncertainty, got {text!r}")
    return Condition(name.strip(), value, u, m.group(3))


def load_run_file(path: str | os.PathLike) -> RunInfo:
    """The run fields of one calibration from a TOML/YAML file: its ``[run]`` table, or its top level.

    Raises
    ------
    InputError
        Unreadable file, bad syntax, unknown field or wrong type.
    """
    p = Path(path)
    doc = _read_doc(p, "run file")
    run = doc.get("run", doc)
    if not isinstance(run, Mapping):
        raise InputError(f"run file {p}: 'run' must be a table")
    return run_info_from(run, f"{p} [run]" if "run" in doc else str(p))


def signing_approvers(info: CertificateInfo) -> tuple[Person, ...]:
    """Who authorises this certificate: the run's ``approver`` (one of the lab's), else every approver listed.

    Shared by the HTML/PDF certificate and the DCC so both name the same people.

    Raises
    ------
    InputError
        ``run.approver`` is not among the lab's approvers.
    """
    if not info.run.approver:
        return info.lab.approvers
    chosen = tuple(a for a in info.lab.approvers if a.name == info.run.approver)
    if not chosen:
        raise InputError(f"approver {info.run.approver!r} is not among the lab's approvers "
                         f"({', '.join(a.name for a in info.lab.approvers) or 'none listed'}); "
                         "add them to the lab profile or choose one of those")
    return chosen


def example_info(*, item: str, model: str, serial: str, certificate_id: str,
                 standards: Sequence[Standard] | None = None) -> CertificateInfo:
    """A filled-in, fictitious lab and run for one item: what ``senscal demo`` certifies its simulated sensors with.

    Every required field is given (no DRAFT mark) and every value says it
    is fictitious or simulated, so a demo certificate cannot pass for a real one.
    Its standards are in date (due a year from today) and state that they
    are simulated, so the certificate claims no traceability to the SI.
    """
    import datetime as _dt

    due = (_dt.date.today() + _dt.timedelta(days=365)).isoformat()
    if standards is None:
        standards = (Standard("Double centrifuge (simulated)", "SIM-001", "SIM-CERT-0001", "none: simulated data",
                              due, 0.0005),)
    lab = LabProfile(name="senscal demo laboratory (fictitious)", address="1 Example Street\n12345 Example Town",
                     accreditation="none: demonstration only", procedure="DEMO-VIB-01", email="lab@example.org",
                     country="DE", approvers=(Person("A. Example", "Head of laboratory (fictitious)"),),
                     standards=tuple(standards))
    run = RunInfo(certificate_id=certificate_id, customer="Demo customer (fictitious)",
                  customer_address="2 Example Road, 12345 Example Town", customer_email="customer@example.org",
                  item=item, manufacturer="senscal simulator", model=model, serial=serial,
                  calibration_date=_dt.date.today().isoformat(), location="senscal demo (simulated recordings)",
                  conditions=(Condition("temperature (simulated)", 23.0, 0.5, "degC"),),
                  remarks="Simulated recordings with known truth: this certificate shows the format; it is not a "
                          "calibration.")
    return CertificateInfo(lab, run)
