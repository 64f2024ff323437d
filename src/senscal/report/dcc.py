"""Digital Calibration Certificate (DCC) XML for senscal's calibrations.

Writes the PTB DCC (schema 3.1.2, D-SI 2.1.0) of a frequency response,
a velocity-sensor sensitivity, an amplitude linearity, a three-axis sensor
calibration or a shaft gravity model: administrative data
from the lab profile and the run (:class:`senscal.report.lab.CertificateInfo`),
measurement results as D-SI lists (``si:realListXMLList``, ``si:hybrid`` for
phases in degrees and radians) with expanded uncertainties, coverage factors
and coverage probabilities. Every document is validated against the vendored
schemas (``senscal/report/schemas``, offline) before it is returned or
written; an invalid one raises :class:`DccError` naming the first violation.

The XML is built with :mod:`xml.etree.ElementTree`, which escapes ``<``,
``&`` and quotes in every user string; characters XML 1.0 cannot hold at all
(control characters other than tab, line feed and carriage return) are
refused with the field that carries them, never stripped silently.

References
----------
.. [1] S. Hackel et al., "The Digital Calibration Certificate", PTB-Mitteilungen
   127 (2017) 75-81; schema documentation https://ptb.de/dcc/v3.1.2/.
.. [2] D. Hutzschenreuter et al., "SmartCom Digital System of Units (D-SI)
   Guide for the use of the metadata-format used in metrology for the
   easy-to-use, safe, harmonised and unambiguous digital transfer of metrological
   data", version 2.1.0, Zenodo (2021), doi:10.5281/zenodo.3816686.
.. [3] ISO/IEC 17025:2017, 7.8 (reporting of results); JCGM 100:2008 (GUM), 6.2.
"""

from __future__ import annotations

import datetime as _dt
import functools
import math
import re
import unicodedata
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path
from typing import Any, Sequence

from senscal.errors import InputError
from senscal.report.lab import CertificateInfo, missing_fields, signing_approvers, traceability_claim

__all__ = ["DccError", "write_dcc", "dcc_xml", "validate_dcc", "dcc_schema", "dsi_unit", "dcc_missing_fields",
           "read_dcc_quantities", "DCC_NS", "SI_NS", "SCHEMA_VERSION", "COVERAGE_PROBABILITY"]

DCC_NS = "https://ptb.de/dcc"
SI_NS = "https://ptb.de/si"
SCHEMA_VERSION = "3.1.2"
# senscal's coverage factors are k = 2 or Student's t for the normal
# distribution's two-sided 95.45 % (senscal.vibration.budget), so that is the
# probability the certificate states, not a rounded 95 %.
COVERAGE_PROBABILITY = "0.9545"

ET.register_namespace("dcc", DCC_NS)
ET.register_namespace("si", SI_NS)

# Fields the DCC schema makes mandatory beyond the ISO/IEC 17025 set of
# senscal.report.lab.missing_fields (contactType needs an e-mail and a
# location, coreData a country code and a unique identifier, an item its
# manufacturer).
DCC_REQUIRED_LAB = ("email", "country")
DCC_REQUIRED_RUN = ("certificate_id", "customer_address", "customer_email", "manufacturer")

_TITLES = {"response": "Accelerometer frequency response", "velocity": "Velocity-sensor sensitivity",
           "linearity": "Accelerometer amplitude linearity", "triaxial": "Three-axis sensor calibration",
           "shaft": "Tangential accelerometer on a rotating shaft: gravity model",
           "imu": "IMU accelerometer and gyroscope calibration", "shock": "Accelerometer shock sensitivity"}
_METHODS = {"shock": "Shock calibration from half-sine pulses: peak ratio of the output to the acceleration (a reference "
                     "accelerometer, ISO 16063-22, or a laser differentiated with a stated filter, ISO 16063-13) and "
                     "the transfer function from the pulses' spectra",
            "triaxial": "Three-axis sensor calibration from readings in many orientations in a field of constant "
                        "magnitude: scale factors, non-orthogonality angles and offsets (maximum likelihood)",
            "imu": "Multi-pose IMU calibration (IMU-TK protocol): accelerometer by maximum likelihood on the static "
                   "pose means, gyroscope by integrating the rotations between poses (quaternion RK4), optionally "
                   "with rate-table segments of known rate",
            "shaft": "Gravity identification of a tangential accelerometer on a shaft turning at constant speed: "
                     "amplitude, phase and offset of the gravity term against the encoder angle",
            "response": "Sine-excitation calibration: sensitivity and phase delay per frequency, least-squares sine "
                        "fits of output and reference (GUM uncertainty budget per point)",
            "velocity": "Sine-excitation calibration of a velocity sensor against a position reference: "
                        "sensitivity and phase per frequency and their weighted mean",
            "linearity": "Sine-excitation calibration at several amplitudes: best straight line through the output "
                         "amplitudes and the largest deviation from it (Monte Carlo uncertainty, JCGM 101)"}


class DccError(InputError):
    """A DCC cannot be written: missing administrative data, an unusable string or unit, or a schema violation."""


# ---------------------------------------------------------------------------
# schema


def _schema_dir() -> Path:
    from importlib.resources import files

    return Path(str(files("senscal.report") / "schemas"))


@functools.lru_cache(maxsize=1)
def dcc_schema():
    """The DCC 3.1.2 schema with D-SI 2.1.0, loaded from the vendored copies only.

    The import of D-SI names a web address in ``dcc.xsd``; it is mapped to the
    local ``SI_Format.xsd`` and remote access is forbidden (``allow="local"``),
    so validation works offline and never waits on a network.

    Returns
    -------
    xmlschema.XMLSchema
    """
    import xmlschema

    d = _schema_dir()
    return xmlschema.XMLSchema(str(d / "dcc.xsd"), locations={SI_NS: str(d / "SI_Format.xsd")}, allow="local")


def validate_dcc(xml: bytes | str) -> None:
    """Check a DCC document against the vendored schema.

    Parameters
    ----------
    xml : bytes or str
        The document.

    Raises
    ------
    DccError
        Not well-formed XML, or the first schema violation as one line:
        its path in the document and the reason.
    """
    data = xml.encode("utf-8") if isinstance(xml, str) else xml
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise DccError(f"DCC is not well-formed XML ({exc}); this is a bug, please report it") from None
    for err in dcc_schema().iter_errors(root):
        reason = " ".join(str(err.reason or err.message).split())
        raise DccError(f"DCC does not validate against dcc.xsd {SCHEMA_VERSION}: {err.path}: {reason}")


# ---------------------------------------------------------------------------
# units

_DSI_UNITS = {
    "m": "metre", "s": "second", "A": "ampere", "K": "kelvin", "mol": "mole", "cd": "candela",
    "rad": "radian", "sr": "steradian", "Hz": "hertz", "N": "newton", "Pa": "pascal", "J": "joule",
    "W": "watt", "C": "coulomb", "V": "volt", "F": "farad", "Ohm": "ohm", "ohm": "ohm", "\u03a9": "ohm",
    "S": "siemens", "Wb": "weber", "T": "tesla", "H": "henry", "L": "litre", "l": "litre", "bar": "bar",
}
# Units that take no SI prefix (and would be misread with one: "min", "h", "deg").
_DSI_PLAIN = {"1": "one", "%": "percent", "deg": "degree", "\u00b0": "degree", "degC": "degreecelsius",
              "\u00b0C": "degreecelsius", "%RH": "percent", "min": "minute", "h": "hour", "d": "day",
              "kg": "kilogram"}
_DSI_PREFIX = {"y": "yocto", "z": "zepto", "a": "atto", "f": "femto", "p": "pico", "n": "nano", "u": "micro",
               "\u00b5": "micro", "\u03bc": "micro", "m": "milli", "c": "centi", "d": "deci", "da": "deca",
               "h": "hecto", "k": "kilo", "M": "mega", "G": "giga", "T": "tera", "P": "peta"}
_TOKEN = re.compile(r"\s*(\(|\)|/|\*|\u00b7|\^|-?\d+(?:\.\d+)?|[A-Za-z\u00b5\u03bc\u03a9\u00b0%]+)")


def _dsi_symbol(sym: str, whole: str) -> tuple[str, str]:
    if sym in ("g", "gn", "gram"):
        # "mV/g" on an accelerometer data sheet means per standard gravity, not per gram
        raise DccError(f"unit {whole!r}: 'g' is ambiguous (gram or standard gravity) and D-SI has no standard "
                       f"gravity; give the sensitivity per m/s^2 (e.g. --output-unit V and the result in V/(m/s^2))")
    if sym in _DSI_PLAIN:
        return "", _DSI_PLAIN[sym]
    if sym in _DSI_UNITS:
        return "", _DSI_UNITS[sym]
    for n in (2, 1):
        if len(sym) > n and sym[:n] in _DSI_PREFIX and sym[n:] in _DSI_UNITS:
            return _DSI_PREFIX[sym[:n]], _DSI_UNITS[sym[n:]]
        if len(sym) > n and sym[:n] in _DSI_PREFIX and sym[n:] == "g":
            return _DSI_PREFIX[sym[:n]], "gram"
    raise DccError(f"unit {whole!r}: {sym!r} has no D-SI form; give the unit in SI symbols "
                   f"(V, mV, pC, m/s^2, Hz, deg, %, degC, ...)")


def dsi_unit(unit: str) -> str:
    """Translate a senscal unit string to a D-SI unit string.

    Parameters
    ----------
    unit : str
        Products, quotients, parentheses and powers of SI symbols with prefixes,
        as senscal writes them: ``"V/(m/s^2)"``, ``"pC/(m/s^2)"``, ``"V/(m/s)"``,
        ``"m/s^2"``, ``"Hz"``, ``"deg"``, ``"%"``, ``"degC"``, ``"1"`` or ``""``
        (dimensionless).

    Returns
    -------
    str
        D-SI 2.1.0 unit, e.g. ``"\\volt\\metre\\tothe{-1}\\second\\tothe{2}"``
        for ``V/(m/s^2)``; ``"\\one"`` for a dimensionless quantity.

    Raises
    ------
    DccError
        A symbol D-SI cannot express or that is ambiguous (``g``).
    """
    whole = unit
    tokens = _TOKEN.findall(unit.strip())
    if "".join(tokens).replace(" ", "") != re.sub(r"\s+", "", unit.strip()):
        raise DccError(f"unit {whole!r} cannot be read; write it as e.g. V/(m/s^2)")
    pos = 0

    def expr() -> list[tuple[str, str, float]]:
        nonlocal pos
        out = term()
        while pos < len(tokens) and tokens[pos] not in (")", "^"):
            op = tokens[pos]
            if op in ("/", "*", "\u00b7"):
                pos += 1
            # else: a space between symbols ("m s^-2") multiplies
            nxt = term()
            out += [(p, u, -e) for p, u, e in nxt] if op == "/" else nxt
        return out

    def term() -> list[tuple[str, str, float]]:
        nonlocal pos
        if pos >= len(tokens):
            raise DccError(f"unit {whole!r} ends too early; write it as e.g. V/(m/s^2)")
        tok = tokens[pos]
        pos += 1
        if tok in (")", "/", "*", "^", "\u00b7"):
            raise DccError(f"unit {whole!r} cannot be read at {tok!r}; write it as e.g. V/(m/s^2)")
        if tok == "(":
            inner = expr()
            if pos >= len(tokens) or tokens[pos] != ")":
                raise DccError(f"unit {whole!r} has an unclosed parenthesis")
            pos += 1
        elif re.fullmatch(r"-?\d+(?:\.\d+)?", tok) and float(tok) == 1:
            inner = []
        else:
            inner = [(*_dsi_symbol(tok, whole), 1.0)]
        if pos < len(tokens) and tokens[pos] == "^":
            pos += 1
            if pos >= len(tokens) or not re.fullmatch(r"-?\d+(?:\.\d+)?", tokens[pos]):
                raise DccError(f"unit {whole!r}: '^' needs a number after it")
            power = float(tokens[pos])
            pos += 1
            inner = [(p, u, e * power) for p, u, e in inner]
        return inner

    if not tokens:
        return "\\one"
    factors = expr()
    if pos != len(tokens):
        raise DccError(f"unit {whole!r} cannot be read at {tokens[pos]!r}; write it as e.g. V/(m/s^2)")
    merged: dict[tuple[str, str], float] = {}
    for p, u, e in factors:
        merged[(p, u)] = merged.get((p, u), 0.0) + e
    parts = []
    for (p, u), e in merged.items():
        if e == 0 or (u == "one" and not p):
            continue
        s = (f"\\{p}" if p else "") + f"\\{u}"
        if e != 1:
            s += "\\tothe{%s}" % (f"{e:g}")
        parts.append(s)
    return "".join(parts) or "\\one"


# ---------------------------------------------------------------------------
# administrative data

_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")


def dcc_missing_fields(info: CertificateInfo) -> list[str]:
    """Fields a DCC needs that ``info`` leaves empty.

    The ISO/IEC 17025 fields of :func:`senscal.report.lab.missing_fields`
    (whose absence makes an HTML/PDF certificate a DRAFT) plus what the DCC
    schema requires: ``lab.email``, ``lab.country``, ``run.certificate_id``,
    ``run.customer_address``, ``run.customer_email``, ``run.manufacturer``.
    A DCC has no DRAFT mark, so it is refused while any is missing.
    """
    out = missing_fields(info)
    out += [f"lab.{n}" for n in DCC_REQUIRED_LAB if not getattr(info.lab, n, "")]
    out += [f"run.{n}" for n in DCC_REQUIRED_RUN if not getattr(info.run, n, "")]
    return out


def _date(text: str, field: str) -> str:
    if not _DATE.fullmatch(text):
        raise DccError(f"{field} {text!r} is not a date; write it as YYYY-MM-DD")
    try:
        _dt.date.fromisoformat(text)
    except ValueError:
        raise DccError(f"{field} {text!r} is not a calendar date; write it as YYYY-MM-DD") from None
    return text


def _performance_dates(text: str) -> tuple[str, str]:
    """``YYYY-MM-DD`` or ``YYYY-MM-DD/YYYY-MM-DD`` (ISO 8601 interval) -> begin, end."""
    parts = [s.strip() for s in text.split("/")]
    if len(parts) > 2:
        raise DccError(f"run.calibration_date {text!r}: give one date or begin/end as YYYY-MM-DD/YYYY-MM-DD")
    begin = _date(parts[0], "run.calibration_date")
    end = _date(parts[-1], "run.calibration_date")
    if end < begin:
        raise DccError(f"run.calibration_date {text!r} ends before it begins; give begin/end in that order")
    return begin, end


_LOCATIONS = {"laboratory": "laboratory", "customer": "customer", "laboratorybranch": "laboratoryBranch",
              "customerbranch": "customerBranch", "other": "other"}


def _check_text(text: Any, field: str) -> str:
    s = "" if text is None else str(text)
    for i, ch in enumerate(s):
        if ch in "\t\n\r":
            continue
        if unicodedata.category(ch) in ("Cc", "Cs") or ch in "\ufffe\uffff":
            raise DccError(f"{field} holds the control character U+{ord(ch):04X} at position {i + 1}, which an XML "
                           f"certificate cannot carry; remove it from the lab profile or the option that gives it")
    return s


class _Builder:
    """ElementTree helpers that route every string through the control-character check."""

    def __init__(self, lang: str):
        self.lang = lang

    @staticmethod
    def el(parent: ET.Element | None, tag: str, text: str | None = None, *, ns: str = DCC_NS,
           field: str = "", **attrib: str) -> ET.Element:
        name = f"{{{ns}}}{tag}"
        e = ET.Element(name, attrib) if parent is None else ET.SubElement(parent, name, attrib)
        if text is not None:
            e.text = _check_text(text, field or tag)
        return e

    def text(self, parent: ET.Element, tag: str, content: str, field: str, **attrib: str) -> ET.Element:
        """A dcc:textType / richContentType element with one localised content."""
        e = self.el(parent, tag, **attrib)
        self.el(e, "content", content, field=field, lang=self.lang)
        return e

    def location(self, parent: ET.Element, address: str, field: str, country: str = "") -> ET.Element:
        loc = self.el(parent, "location")
        if country:
            self.el(loc, "countryCode", country, field="lab.country")
        # one element per address line: a newline inside one text is not how a reader (or the DCC GUI) shows it
        lines = [ln.strip() for ln in re.split(r"[\r\n]+", address) if ln.strip()] or [address]
        for line in lines:
            self.text(loc, "further", line, field)
        return loc

    def contact(self, parent: ET.Element, tag: str, name: str, email: str, address: str, where: str,
                phone: str = "", country: str = "") -> ET.Element:
        c = self.el(parent, tag)
        self.text(c, "name", name, f"{where}.name" if where == "lab" else where)
        self.el(c, "eMail", email, field=f"{where}.email" if where == "lab" else f"{where}_email")
        if phone:
            self.el(c, "phone", phone, field=f"{where}.phone")
        self.location(c, address, f"{where}.address" if where == "lab" else f"{where}_address", country)
        return c

    def statement(self, parent: ET.Element, declaration: str, field: str, *, ref: str = "", date: str = "",
                  traceable: bool | None = None, conformity: str = "") -> ET.Element:
        st = self.el(parent, "statement", **({"refType": ref} if ref else {}))
        if traceable is not None:
            self.el(st, "traceable", "true" if traceable else "false")
        self.text(st, "declaration", declaration, field)
        if date:
            self.el(st, "date", date)
        if conformity:
            self.el(st, "conformity", conformity)
        return st


def _administrative(b: _Builder, root: ET.Element, info: CertificateInfo, today: str) -> None:
    from senscal import __version__

    lab, run = info.lab, info.run
    adm = b.el(root, "administrativeData")
    sw = b.el(b.el(adm, "dccSoftware"), "software")
    b.text(sw, "name", "senscal", "software")
    b.el(sw, "release", __version__)
    b.el(sw, "type", "application")

    core = b.el(adm, "coreData")
    if not re.fullmatch(r"[A-Z]{2}", lab.country):
        raise DccError(f"lab.country {lab.country!r} is not an ISO 3166-1 alpha-2 code; write two capital letters, "
                       f"e.g. DE, FR, GB")
    b.el(core, "countryCodeISO3166_1", lab.country)
    b.el(core, "usedLangCodeISO639_1", b.lang)
    b.el(core, "mandatoryLangCodeISO639_1", b.lang)
    b.el(core, "uniqueIdentifier", run.certificate_id, field="run.certificate_id")
    if run.receipt_date:
        b.el(core, "receiptDate", _date(run.receipt_date, "run.receipt_date"))
    begin, end = _performance_dates(run.calibration_date)
    b.el(core, "beginPerformanceDate", begin)
    b.el(core, "endPerformanceDate", end)
    where = re.sub(r"[\s_'-]+", "", run.location).lower()
    b.el(core, "performanceLocation", _LOCATIONS.get(where, "other"))

    items = b.el(adm, "items")
    item = b.el(items, "item")
    b.text(item, "name", run.item, "run.item")
    man = b.el(item, "manufacturer")
    b.text(man, "name", run.manufacturer, "run.manufacturer")
    if run.model:
        b.el(item, "model", run.model, field="run.model")
    ident = b.el(b.el(item, "identifications"), "identification")
    b.el(ident, "issuer", "manufacturer")
    b.el(ident, "value", run.serial, field="run.serial")
    b.text(ident, "name", "Serial number", "serial")

    cal = b.el(adm, "calibrationLaboratory")
    if lab.accreditation:
        b.el(cal, "calibrationLaboratoryCode", lab.accreditation, field="lab.accreditation")
    b.contact(cal, "contact", lab.name, lab.email, lab.address, "lab", lab.phone, lab.country)

    persons = b.el(adm, "respPersons")
    for i, a in enumerate(signing_approvers(info)):
        rp = b.el(persons, "respPerson")
        b.text(b.el(rp, "person"), "name", a.name, "lab.approvers.name")
        if a.role:
            b.el(rp, "role", a.role, field="lab.approvers.role")
        b.el(rp, "mainSigner", "true" if i == 0 else "false")

    b.contact(adm, "customer", run.customer, run.customer_email, run.customer_address, "run.customer")

    sts = b.el(adm, "statements")
    issue = _date(run.issue_date, "run.issue_date") if run.issue_date else today
    b.statement(sts, "Date of issue of this certificate.", "", ref="senscal_issueDate", date=issue)
    b.statement(sts, f"Location of the calibration: {run.location}", "run.location", ref="senscal_location")
    b.statement(sts, "The results relate only to the item calibrated, under the conditions stated. This certificate "
                     "shall not be reproduced except in full.", "", ref="senscal_scope")
    b.statement(sts, "U is the expanded uncertainty, the standard uncertainty (GUM, JCGM 100:2008) multiplied by the "
                     "coverage factor k: 2 for many degrees of freedom, Student's t for the same coverage probability "
                     f"{COVERAGE_PROBABILITY} where they are few.", "", ref="senscal_uncertainty")
    if lab.standards:
        # the claim follows from the standards (the same rule as the HTML/PDF certificate)
        claimed, sentence = traceability_claim(lab.standards)
        trace = "; ".join(f"{s.name}: {s.traceability}" for s in lab.standards if s.traceability)
        if claimed:
            sentence = ("The measurements are traceable to national standards through the reference standards "
                        "listed with the results" + (f" ({trace})." if trace else "."))
        b.statement(sts, sentence, "lab.standards.traceability", ref="senscal_traceability", traceable=claimed)
    if run.conformity:
        rule = f" Decision rule: {run.decision_rule}" if run.decision_rule else ""
        from senscal.report.conformity import dcc_conformity

        # "conditional pass (...)" as the schema's conditionalPass; free text gets no enumerated value
        b.statement(sts, f"Statement of conformity: {run.conformity}.{rule}", "run.conformity",
                    ref="senscal_conformity", conformity=dcc_conformity(run.conformity))
    if run.deviations:
        b.statement(sts, f"Deviations from the method: {run.deviations}", "run.deviations", ref="senscal_deviations")
    if run.remarks:
        b.statement(sts, run.remarks, "run.remarks", ref="senscal_remarks")


# ---------------------------------------------------------------------------
# measurement results


def _num(x: float, what: str) -> str:
    """The value to 12 significant digits, as the shortest decimal of that (no float noise such as
    ``0.10000000000000003``; 12 digits are far below any uncertainty a calibration states)."""
    v = float(x)
    if not math.isfinite(v):
        raise DccError(f"{what} is {v}; a certificate cannot state a non-finite value, check the result")
    return repr(float(f"{v:.12g}"))


def _k(x: float, what: str) -> str:
    """The coverage factor to 3 significant digits, as the certificate prints it (2, 2.03, 2.87)."""
    v = float(x)
    if not math.isfinite(v) or v < 1:
        raise DccError(f"coverage factor of {what} is {v}; it must be a finite number >= 1")
    s = f"{v:.3g}"
    # D-SI's kValueType allows no exponent
    return s if "e" not in s else f"{v:.0f}"


def _real_list(b: _Builder, parent: ET.Element, label: str, values: Sequence[float], unit: str,
               U: Sequence[float] | None = None, k: Sequence[float] | None = None,
               tag: str = "realListXMLList") -> ET.Element:
    e = b.el(parent, tag, ns=SI_NS)
    b.el(e, "labelXMLList", " ".join([re.sub(r"\s+", "_", label)] * len(values)), ns=SI_NS, field="label")
    b.el(e, "valueXMLList", " ".join(_num(v, label) for v in values), ns=SI_NS)
    b.el(e, "unitXMLList", " ".join([dsi_unit(unit)] * len(values)), ns=SI_NS, field="unit")
    if U is not None:
        unc = b.el(e, "expandedUncXMLList", ns=SI_NS)
        b.el(unc, "uncertaintyXMLList", " ".join(_num(u, f"U of {label}") for u in U), ns=SI_NS)
        b.el(unc, "coverageFactorXMLList", " ".join(_k(x, label) for x in (k or [2.0] * len(values))), ns=SI_NS)
        b.el(unc, "coverageProbabilityXMLList", " ".join([COVERAGE_PROBABILITY] * len(values)), ns=SI_NS)
        b.el(unc, "distributionXMLList", " ".join(["normal"] * len(values)), ns=SI_NS)
    return e


def _real(b: _Builder, parent: ET.Element, label: str, value: float, unit: str, U: float | None = None,
          k: float = 2.0) -> ET.Element:
    e = b.el(parent, "real", ns=SI_NS)
    b.el(e, "label", label, ns=SI_NS)
    b.el(e, "value", _num(value, label), ns=SI_NS)
    b.el(e, "unit", dsi_unit(unit), ns=SI_NS, field="unit")
    if U is not None:
        unc = b.el(e, "expandedUnc", ns=SI_NS)
        b.el(unc, "uncertainty", _num(U, f"U of {label}"), ns=SI_NS)
        b.el(unc, "coverageFactor", _k(k, label), ns=SI_NS)
        b.el(unc, "coverageProbability", COVERAGE_PROBABILITY, ns=SI_NS)
        b.el(unc, "distribution", "normal", ns=SI_NS)
    return e


def _quantity(b: _Builder, parent: ET.Element, name: str, ref: str) -> ET.Element:
    q = b.el(parent, "quantity", refType=ref)
    b.text(q, "name", name, "quantity name")
    return q


def _list_quantity(b: _Builder, lst: ET.Element, name: str, ref: str, values, unit, U=None, k=None) -> None:
    _real_list(b, _quantity(b, lst, name, ref), ref, values, unit, U, k)


def _phase_quantity(b: _Builder, lst: ET.Element, name: str, ref: str, rad, U_rad, k) -> None:
    """Phase as si:hybrid: the same values (and expanded U) in degrees and in radians."""
    hyb = b.el(_quantity(b, lst, name, ref), "hybrid", ns=SI_NS)
    _real_list(b, hyb, ref, [math.degrees(v) for v in rad], "deg", [math.degrees(x) for x in U_rad], k)
    _real_list(b, hyb, ref, list(rad), "rad", list(U_rad), k)


def _result(b: _Builder, results: ET.Element, name: str, ref: str, description: str = "") -> ET.Element:
    r = b.el(results, "result", refType=ref)
    b.text(r, "name", name, "result name")
    if description:
        b.text(r, "description", description, "result description")
    return b.el(r, "data")


def _point_list(b: _Builder, data: ET.Element, name: str) -> ET.Element:
    lst = b.el(data, "list")
    b.text(lst, "name", name, "list name")
    return lst


def _budget_U(budgets, u, what: str) -> tuple[list[float], list[float]]:
    """Expanded U and k per point: the budget's own when there is one, else k = 2 on ``u``."""
    U, k = [], []
    for bud, ui in zip(budgets, u):
        if bud is not None:
            U.append(bud.expanded)
            k.append(bud.coverage_factor)
        elif ui is None:
            raise DccError(f"{what} has a point without uncertainty; a certificate needs every U")
        else:
            U.append(2.0 * ui)
            k.append(2.0)
    return U, k


def _output_unit(unit: str) -> str:
    for tail in ("/(m/s^2)", "/(m s^-2)", "/(m*s^-2)"):
        if unit.endswith(tail):
            return unit[: -len(tail)]
    raise DccError(f"sensitivity unit {unit!r} is not 'output unit per m/s^2' (e.g. V/(m/s^2)); give unit= so")


def _response_points(b: _Builder, results: ET.Element, pts: Sequence[Any], unit: str, name: str, ref: str,
                     description: str) -> None:
    """One result with the point lists; quantity refTypes are ``senscal_<ref>`` + the quantity's name."""
    lst = _point_list(b, _result(b, results, name, f"senscal_{ref}", description), "Calibration points")
    tag = ref[0].upper() + ref[1:] if ref != "frequencyResponse" else ""
    f = [p.frequency for p in pts]
    uf = [getattr(p, "u_frequency", None) for p in pts]
    has_uf = all(u is not None for u in uf)
    _list_quantity(b, lst, "Frequency", f"senscal_frequency{tag}", f, "Hz",
                   [2.0 * u for u in uf] if has_uf else None, [2.0] * len(f) if has_uf else None)
    U, k = _budget_U([p.sensitivity_budget for p in pts], [p.u_sensitivity for p in pts], "sensitivity")
    _list_quantity(b, lst, "Sensitivity", f"senscal_sensitivity{tag}", [p.sensitivity for p in pts], unit, U, k)
    if all(p.normalized_sensitivity is not None for p in pts):
        U, k = _budget_U([p.normalized_budget for p in pts], [p.u_normalized_sensitivity for p in pts],
                         "normalized sensitivity")
        _list_quantity(b, lst, "Normalized sensitivity S_i/S_0", f"senscal_normalizedSensitivity{tag}",
                       [p.normalized_sensitivity for p in pts], "1", U, k)
    if all(p.phase_delay is not None for p in pts):
        U, k = _budget_U([p.phase_delay_budget for p in pts], [p.u_phase_delay for p in pts], "phase delay")
        _phase_quantity(b, lst, "Phase delay (output minus input)", f"senscal_phaseDelay{tag}",
                        [p.phase_delay for p in pts], U, k)


def _response_results(b: _Builder, results: ET.Element, resp: Any, unit: str, job: Any = None) -> None:
    ref = getattr(resp, "phase_reference", "")
    _response_points(b, results, resp.points, unit, "Frequency response", "frequencyResponse",
                     f"Input phase reference: {ref}" if ref else "")
    repeats = tuple(getattr(job, "repeats", ()) or ())
    if repeats and len(repeats) < len(resp.points):
        # some frequency was recorded more than once: the per-frequency means are the values to quote
        _response_points(b, results, repeats, unit, "Frequency response, repeated records combined", "repeats",
                         "Mean per frequency of the records above, with the spread between them in U")


def _velocity_results(b: _Builder, results: ET.Element, cal: Any, unit: str, job: Any = None) -> None:
    data = _result(b, results, "Sensitivity", "senscal_velocitySensitivity",
                   f"Weighted mean over {len(cal.points)} frequencies")
    bud = cal.budget
    _real(b, _quantity(b, data, "Sensitivity", "senscal_meanSensitivity"), "sensitivity", cal.sensitivity, unit,
          bud.expanded if bud is not None else 2.0 * cal.u_sensitivity, bud.coverage_factor if bud is not None else 2.0)
    pts = cal.points
    lst = _point_list(b, _result(b, results, "Sensitivity per frequency", "senscal_velocityPoints"),
                      "Calibration points")
    _list_quantity(b, lst, "Frequency", "senscal_frequency", [p.frequency for p in pts], "Hz",
                   [2.0 * p.u_frequency for p in pts], [2.0] * len(pts))
    U, k = _budget_U([p.budget for p in pts], [p.u_sensitivity for p in pts], "sensitivity")
    _list_quantity(b, lst, "Sensitivity", "senscal_sensitivity", [p.sensitivity for p in pts], unit, U, k)
    _phase_quantity(b, lst, "Phase of the output against the velocity", "senscal_phase",
                    [p.phase for p in pts], [2.0 * p.u_phase for p in pts], [2.0] * len(pts))


def _linearity_results(b: _Builder, results: ET.Element, lin: Any, unit: str, job: Any = None) -> None:
    out_unit = getattr(job, "output_unit", "") or _output_unit(unit)
    k = getattr(lin, "coverage_factor", 2.0)
    resolved = getattr(lin, "linearity_resolved", None)
    desc = "Largest deviation from the best straight line, relative to the full-scale output"
    if resolved is False:
        desc += (f"; not resolved: the deviations are within the noise, the linearity is below "
                 f"{lin.linearity_bound_percent:.2g} % (95.45 % Monte-Carlo bound)")
    data = _result(b, results, "Amplitude linearity", "senscal_linearity", desc)
    _real(b, _quantity(b, data, "Amplitude linearity", "senscal_linearityPercent"), "linearity",
          lin.linearity_percent, "%", 2.0 * lin.u_linearity_percent, 2.0)
    if math.isfinite(getattr(lin, "linearity_bound_percent", math.nan)):
        _real(b, _quantity(b, data, "Upper bound of the linearity (95.45 %)", "senscal_linearityBound"),
              "linearity_bound", lin.linearity_bound_percent, "%")
    _real(b, _quantity(b, data, "Full-scale output", "senscal_fullScaleOutput"), "full_scale_output",
          lin.full_scale_output, out_unit)
    data = _result(b, results, "Sensitivity (slope of the best straight line)", "senscal_slope")
    _real(b, _quantity(b, data, "Sensitivity", "senscal_sensitivity"), "slope", lin.slope, unit, k * lin.u_slope, k)
    _real(b, _quantity(b, data, "Intercept", "senscal_intercept"), "intercept", lin.intercept, out_unit,
          k * lin.u_intercept, k)
    pts = lin.points
    lst = _point_list(b, _result(b, results, "Amplitude points", "senscal_linearityPoints"), "Calibration points")
    _list_quantity(b, lst, "Input amplitude (peak)", "senscal_inputAmplitude", [p.input_amplitude for p in pts],
                   "m/s^2")
    _list_quantity(b, lst, "Output amplitude (peak)", "senscal_outputAmplitude", [p.output_amplitude for p in pts],
                   out_unit, [2.0 * p.u_output_amplitude for p in pts], [2.0] * len(pts))
    _list_quantity(b, lst, "Deviation from the straight line", "senscal_deviation", [p.deviation for p in pts],
                   out_unit)
    _list_quantity(b, lst, "Deviation relative to full scale", "senscal_deviationPercent",
                   [p.deviation_percent for p in pts], "%")


def _parameter(b: _Builder, data: ET.Element, name: str, value: Any, u: Any, unit: str, k: float = 2.0,
               why: str = "") -> None:
    """One identified parameter: si:real with U = k u; angles (rad) as si:hybrid in deg and rad."""
    q = _quantity(b, data, name, f"senscal_{name}")
    v = float("nan") if value is None else float(value)
    uu = float("nan") if u is None else float(u)
    if not (math.isfinite(v) and math.isfinite(uu)):
        # the data do not determine it: say so instead of a number
        b.text(q, "noQuantity", f"{name}: not determined by these data" + (f" ({why})" if why else ""), "parameter")
        return
    if not unit:
        raise DccError(f"parameter {name} has no unit (the recording's channels carry none); give the unit in the "
                       f"file header, e.g. 'x [nT]', and calibrate again")
    if unit == "rad":
        hyb = b.el(q, "hybrid", ns=SI_NS)
        _real(b, hyb, name, math.degrees(v), "deg", math.degrees(k * uu), k)
        _real(b, hyb, name, v, "rad", k * uu, k)
    else:
        _real(b, q, name, v, unit, k * uu, k)


def _triaxial_results(b: _Builder, results: ET.Element, tri: Any, unit: str, job: Any = None) -> None:
    parts = [("Calibration parameters", "senscal_triaxial", tri)]
    if getattr(job, "accelerometer", None) is not None:
        parts.append(("Accelerometer calibration parameters", "senscal_triaxialAccelerometer", job.accelerometer))
    for title, ref, res in parts:
        why = "; ".join(str(g.get("reason", "")) for g in getattr(res, "unidentifiable", ()) if g.get("reason"))
        data = _result(b, results, title, ref, f"Model {res.model}, estimator {res.method}; {res.n_used} of "
                                               f"{res.n_samples} samples used")
        for name, p in res.parameters.items():
            _parameter(b, data, name if ref == "senscal_triaxial" else f"accelerometer_{name}", p.get("value"),
                       p.get("u"), str(p.get("unit") or ""), why=why)


def _shaft_results(b: _Builder, results: ET.Element, m: Any, unit: str, job: Any = None) -> None:
    out = m.output_unit or getattr(job, "accel_unit", "")
    data = _result(b, results, "Gravity model", "senscal_gravityModel",
                   "gravity(theta) = amplitude sin(theta + phase) + offset, theta the encoder angle; "
                   f"{m.revolutions:.1f} revolutions, {m.n_samples} samples")
    for name, v, u, un in (("gravity_amplitude", m.amplitude, m.u_amplitude, out), ("phase", m.phase, m.u_phase, "rad"),
                           ("offset", m.offset, m.u_offset, out), ("tilt", m.tilt, m.u_tilt, "rad"),
                           ("bias", m.bias, m.u_bias, "m/s^2")):
        _parameter(b, data, name, v, u, un)


def _imu_results(b: _Builder, results: ET.Element, res: Any, unit: str, job: Any = None) -> None:
    """Accelerometer and gyroscope of ``senscal imu calibrate`` (``ImuCalibrateResult``): U = 2 u per parameter."""
    from senscal.imu import ACCEL_NAMES, GYRO_ANGLES
    from senscal.units import compatible

    if job is None or not hasattr(job, "budget"):
        raise DccError("an IMU DCC needs the job's result (senscal.jobs.imu.imu_calibrate), not the engine's")

    def reading(u: str, what: str) -> str:
        if not u:
            raise DccError(f"the {what} channels carry no unit; give it in the file header (e.g. 'ax [m/s^2]') and "
                           "calibrate again")
        # counts are a number: a count per m/s^2 is stated as 1/(m/s^2)
        return "1" if compatible(u, "count") else u

    def per(num: str, den: str) -> str:
        return "1" if num == den else (f"1/({den})" if num == "1" else f"{num}/({den})")

    au, gu = reading(job.accel_unit, "accelerometer"), reading(job.gyro_unit, "gyroscope")
    ua = [float(x) for x in (res.accel_covariance.diagonal().clip(0) ** 0.5)]
    st = res.poses.static
    data = _result(b, results, "Accelerometer calibration parameters", "senscal_imuAccelerometer",
                   f"reading = M f + B, M upper triangular (scale factors, non-orthogonality angles), maximum "
                   f"likelihood on |f| = g = {res.gravity:g} m/s^2 over {st.n_poses} static poses")
    units = {"K": per(au, "m/s^2"), "B": au}
    for i, n in enumerate(ACCEL_NAMES):
        _parameter(b, data, f"accelerometer_{n}", res.accel_values[i], ua[i], units.get(n[0], "rad"))
    g = res.gyroscope
    rt = res.rate_table
    desc = ("reading = M w + b(t), M full (scale factors, misalignment to the accelerometer's frame), by integrating "
            "the rotation between static poses")
    if rt is not None:
        desc += (f" combined with {job.rate_table.n_segments} rate-table segments of known rate (consistency chi2 "
                 f"{rt.chi2:.3g} for {rt.dof} dof)")
    data = _result(b, results, "Gyroscope calibration parameters", "senscal_imuGyroscope", desc)
    for i, ax in enumerate("xyz"):
        _parameter(b, data, f"gyroscope_scale_{ax}", g.scale[i], g.u_scale[i], per(gu, "rad/s"))
    for i, n in enumerate(GYRO_ANGLES):
        _parameter(b, data, f"gyroscope_misalignment_{n}", g.angles[i], g.u_angles[i], "rad")
    for i, ax in enumerate("xyz"):
        _parameter(b, data, f"gyroscope_bias_{ax}", g.bias[i], g.u_bias[i], gu)
    if g.g_sensitivity is not None:
        for i, ax in enumerate("xyz"):
            for j, fx in enumerate("xyz"):
                _parameter(b, data, f"gyroscope_g_sensitivity_{ax}{fx}", g.g_sensitivity[i, j],
                           g.u_g_sensitivity[i, j], per(gu, "m/s^2"))
    te = res.temperature
    if te is not None:
        data = _result(b, results, "Reference temperature", "senscal_imuReferenceTemperature",
                       "biases and scales above hold at this temperature (the static poses' mean)")
        _real(b, _quantity(b, data, "Reference temperature", "senscal_referenceTemperature"), "reference_temperature",
              te.reference, job.temp_unit or "degC")


def _shock_results(b: _Builder, results: ET.Element, job: Any, unit: str, _job: Any = None) -> None:
    """``senscal shock`` (``ShockResult``): a list of pulses (duration, peak, shock sensitivity with the budget's
    U), then each pulse's transfer function (magnitude with U, phase as si:hybrid)."""
    pulses, labels = job.pulses, [f"{src} #{p.index}" for src, p in zip(job.sources, job.pulses)]
    lst = _point_list(b, _result(b, results, "Shock sensitivity", "senscal_shockSensitivity",
                                 f"Pulses in order: {'; '.join(labels)}. Filter: {job.filter}"), "Pulses")
    _list_quantity(b, lst, "Pulse duration", "senscal_pulseDuration", [1e-3 * p.duration_ms for p in pulses], "s")
    _list_quantity(b, lst, "Peak acceleration", "senscal_peakAcceleration", [abs(p.peak_acceleration) for p in pulses],
                   "m/s^2", [2.0 * p.u_peak_acceleration for p in pulses], [2.0] * len(pulses))
    U, k = _budget_U(job.budgets(_output_unit(unit)), [p.u_sensitivity for p in pulses], "shock sensitivity")
    _list_quantity(b, lst, "Shock sensitivity (peak ratio)", "senscal_sensitivity", [p.sensitivity for p in pulses],
                   unit, U, k)
    for lab, p in zip(labels, pulses):
        tf = p.transfer_function
        n = len(tf.frequency_hz)
        tl = _point_list(b, _result(b, results, f"Transfer function, {lab}", "senscal_shockTransferFunction",
                                    "Ratio of the spectra of the output and the acceleration over the pulse and its "
                                    "settling; U from the noise (magnitude also the type B terms)"), "Frequencies")
        _list_quantity(b, tl, "Frequency", "senscal_frequency", list(tf.frequency_hz), "Hz")
        _list_quantity(b, tl, "Magnitude", "senscal_transferMagnitude", list(tf.magnitude), unit,
                       [2.0 * u for u in tf.u_magnitude], [2.0] * n)
        _phase_quantity(b, tl, "Phase (output minus acceleration)", "senscal_transferPhase",
                        [math.radians(v) for v in tf.phase_deg], [2.0 * math.radians(u) for u in tf.u_phase_deg],
                        [2.0] * n)


_RESULTS = {"response": _response_results, "velocity": _velocity_results, "linearity": _linearity_results,
            "triaxial": _triaxial_results, "shaft": _shaft_results, "imu": _imu_results, "shock": _shock_results}
# attribute of the senscal.jobs result that holds the engine result
_ENGINE = {"response": "response", "velocity": "calibration", "linearity": "linearity", "triaxial": "calibration",
           "shaft": "model", "imu": "result"}
_KIND_ALIASES = {"triaxial-calibrate": "triaxial", "shaft-calibrate": "shaft", "imu-calibrate": "imu"}


def _measurement(b: _Builder, root: ET.Element, kind: str, result: Any, info: CertificateInfo, unit: str,
                 method: str, files: Sequence[str], warnings: Sequence[str], job: Any) -> None:
    from senscal import __version__

    mr = b.el(b.el(root, "measurementResults"), "measurementResult")
    b.text(mr, "name", _TITLES[kind], "title")
    if files:
        b.text(mr, "description", "Records: " + ", ".join(map(str, files)), "files")
    um = b.el(b.el(mr, "usedMethods"), "usedMethod")
    b.text(um, "name", method or _METHODS[kind], "method")
    if info.lab.procedure:
        b.el(um, "reference", info.lab.procedure, field="lab.procedure")
    sw = b.el(b.el(mr, "usedSoftware"), "software")
    b.text(sw, "name", "senscal", "software")
    b.el(sw, "release", __version__)
    if info.lab.standards:
        eqs = b.el(mr, "measuringEquipments")
        for i, s in enumerate(info.lab.standards):
            where = f"lab.standards[{i}]"
            eq = b.el(eqs, "measuringEquipment", refType="senscal_referenceStandard")
            b.text(eq, "name", s.name, f"{where}.name")
            desc = [f"Calibration certificate: {s.certificate}" if s.certificate else "",
                    f"Traceability: {s.traceability}" if s.traceability else "",
                    f"Calibration due: {s.due}" if s.due else ""]
            if any(desc):
                b.text(eq, "description", "; ".join(d for d in desc if d), where)
            sha = getattr(s, "certificate_sha256", "")
            if sha:
                # hashType: a link to the standard's own DCC that a reader can check byte for byte.
                link = b.el(eq, "certificate")
                b.text(link, "referral", f"Calibration certificate of the reference standard {s.name}", where)
                b.el(link, "referralID", s.certificate or s.name, field=f"{where}.certificate")
                b.el(link, "procedure", "SHA256 of the certificate file", field=where)
                b.el(link, "value", sha, field=f"{where}.certificate_sha256")
            ids = [("manufacturer", s.serial, "Serial number"), ("other", s.certificate, "Calibration certificate")]
            if any(v for _, v, _ in ids):
                il = b.el(eq, "identifications")
                for issuer, value, label in ids:
                    if value:
                        ident = b.el(il, "identification")
                        b.el(ident, "issuer", issuer)
                        b.el(ident, "value", value, field=where)
                        b.text(ident, "name", label, where)
            if s.u_relative is not None:
                mq = b.el(b.el(eq, "measuringEquipmentQuantities"), "measuringEquipmentQuantity",
                          refType="senscal_relativeStandardUncertainty")
                b.text(mq, "name", "Relative standard uncertainty (k=1)", where)
                _real(b, mq, "u_relative", 100.0 * s.u_relative, "%")
    if info.run.conditions:
        ics = b.el(mr, "influenceConditions")
        for c in info.run.conditions:
            ic = b.el(ics, "influenceCondition")
            b.text(ic, "name", c.name, f"run.conditions.{c.name}")
            q = b.el(b.el(ic, "data"), "quantity")
            # Condition u is a standard uncertainty (senscal's convention, k=1): stated as U = 2u, k = 2
            _real(b, q, re.sub(r"\s+", "_", c.name), c.value, c.unit,
                  None if c.uncertainty is None else 2.0 * c.uncertainty, 2.0)
    results = b.el(mr, "results")
    _RESULTS[kind](b, results, result, unit, job)
    if warnings:
        md = b.el(mr, "measurementMetaData")
        for w in warnings:
            m = b.el(md, "metaData", refType="senscal_warning")
            b.text(m, "declaration", f"Departure from the method's model (not covered by U): {w}", "warning")


def dcc_xml(kind: str, result: Any, info: CertificateInfo, *, unit: str = "", method: str = "",
            files: Sequence[str] = (), warnings: Sequence[str] | None = None, language: str = "en",
            today: _dt.date | None = None, certificate_id: str = "") -> bytes:
    """Build and validate the DCC of one calibration.

    Parameters
    ----------
    kind : str
        ``"response"`` (:class:`~senscal.vibration.FrequencyResponse` or the
        job's ``ResponseResult``: repeated frequencies then add a result with
        the per-frequency means), ``"velocity"``
        (:class:`~senscal.vibration.VelocityCalibration` or ``VelocityResult``)
        , ``"linearity"`` (:class:`~senscal.vibration.AmplitudeLinearity` or
        ``LinearityResult``), ``"triaxial"`` (``TriaxialResult`` or
        ``TriaxialCalibrateResult``: scale factors, angles, offsets, field;
        an accelerometer calibrated alongside adds its own result) or
        ``"shaft"`` (``GravityModel`` or ``ShaftCalibrateResult``: gravity
        amplitude, phase, offset, tilt, bias) or ``"shock"`` (``ShockResult``:
        the pulses' shock sensitivities, each pulse's transfer function). Parameters are stated with
        ``U = 2 u``; one the data do not determine is stated as not determined.
    result : object
        The result of that calibration (SI units; phases in rad; standard
        uncertainties, k=1, with their budgets).
    info : CertificateInfo
        Lab profile and run fields; every field of :func:`dcc_missing_fields`
        must be given.
    unit : str
        Sensitivity unit, e.g. ``"V/(m/s^2)"`` (default: ``result.unit``);
        for linearity the output unit is the part before ``/(m/s^2)``.
    method : str
        Method statement (default: a description of senscal's method).
    files : sequence of str
        Records the result comes from.
    warnings : sequence of str, optional
        Named warnings to state (default: ``result.warnings``).
    language : str
        ISO 639-1 code of the text (default ``"en"``).
    today : date, optional
        Date of issue when ``info.run.issue_date`` is empty (default: today, UTC).
    certificate_id : str, optional
        The DCC's unique identifier when the run has no ``certificate_id``
        (pass :func:`senscal.report.certificate.certificate_id` so the DCC and
        the HTML/PDF certificate of one run carry the same id).

    Returns
    -------
    bytes
        UTF-8 XML that validates against DCC 3.1.2 / D-SI 2.1.0. Expanded
        uncertainties ``U = k u`` per value, ``k`` from the result's budgets
        (2, or Student's t for few degrees of freedom), coverage probability
        0.9545. Numbers are written as the shortest decimal that reads back
        as the same double.

    Raises
    ------
    DccError
        Missing administrative fields (all named in one line), a control
        character in a string, a malformed date or country code, a unit
        without a D-SI form, a non-finite value, or a schema violation.
    """
    kind = _KIND_ALIASES.get(kind, kind)
    if kind not in _RESULTS:
        raise DccError(f"unknown DCC kind {kind!r}; use response, velocity, linearity, triaxial, shaft, imu or shock")
    if not isinstance(info, CertificateInfo):
        raise DccError("info must be a CertificateInfo (lab profile + run fields); see senscal.report.lab")
    if certificate_id and not info.run.certificate_id:
        info = replace(info, run=replace(info.run, certificate_id=certificate_id))
    missing = dcc_missing_fields(info)
    if missing:
        lab = [m for m in missing if m.startswith("lab.")]
        run = [m for m in missing if not m.startswith("lab.")]
        where = [f"{', '.join(lab)} (in the lab profile{' ' + info.lab.source if info.lab.source else ''})"] if lab else []
        where += [f"{', '.join(run)} (the run's fields: certificate options, a run file or the profile's [run] "
                  f"table)"] if run else []
        raise DccError(f"cannot write a DCC: missing {'; '.join(where)}; add them (a DCC has no DRAFT mark, so it "
                       f"is never written with fields missing)")
    if not re.fullmatch(r"[a-z]{2}", language):
        raise DccError(f"language {language!r} is not an ISO 639-1 code; use two lower-case letters, e.g. en")
    from senscal.jobs._base import JobResult

    job = result if isinstance(result, JobResult) else None
    if job is not None:  # a senscal.jobs result: the engine result inside, its unit and warnings around it
        result = getattr(job, _ENGINE[kind]) if kind in _ENGINE else job  # shock: the job result itself
    if kind == "shock" and job is not None and not unit:
        unit = job.sensitivity_unit()  # its `unit` is prose ("V per m/s^2")
    unit = unit or getattr(job, "unit", "") or getattr(result, "unit", "")
    if not unit and kind in ("response", "velocity", "linearity", "shock"):
        raise DccError(f"the {kind} result carries no sensitivity unit; give unit=, e.g. 'V/(m/s^2)'")
    today = today or _dt.datetime.now(_dt.timezone.utc).date()
    b = _Builder(language)
    root = b.el(None, "digitalCalibrationCertificate", schemaVersion=SCHEMA_VERSION)
    _administrative(b, root, info, today.isoformat())
    warns = list(getattr(job or result, "warnings", ()) if warnings is None else warnings)
    _measurement(b, root, kind, result, info, unit, method, files, warns, job)
    ET.indent(root)
    data = ET.tostring(root, encoding="utf-8", xml_declaration=True)
    validate_dcc(data)
    return data


def write_dcc(path: str | Path, kind: str, result: Any, info: CertificateInfo, *, unit: str = "",
              **kw: Any) -> Path:
    """Write :func:`dcc_xml` to ``path`` atomically, after it validated.

    Parameters
    ----------
    path : path-like
        The ``.xml`` file to write (folders created; an input of the running
        command is refused).
    kind, result, info, unit, **kw
        As :func:`dcc_xml`.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    DccError
        As :func:`dcc_xml`; nothing is written then.
    InputError
        ``path`` is not a writable ``.xml`` file.
    """
    from senscal.io.guard import check_output, write_bytes

    path = check_output(path, suffixes=(".xml",), what="DCC")
    data = dcc_xml(kind, result, info, unit=unit, **kw)
    write_bytes(path, data, what="DCC")
    return path


def read_dcc_quantities(xml: bytes | str | Path) -> dict[str, dict[str, list]]:
    """The D-SI numbers of a DCC by the ``refType`` of their quantity.

    Parameters
    ----------
    xml : bytes, str or Path
        The document, or the path of a ``.xml`` file.

    Returns
    -------
    dict
        ``{refType: {"unit": [...], "value": [...], "U": [...], "k": [...],
        "p": [...]}}`` with floats (units as D-SI strings); a phase given as
        ``si:hybrid`` appears once per unit as ``refType@unit``. A refType
        used in several results keeps the first.
    """
    if isinstance(xml, Path):
        from senscal.io.sidefiles import read_text

        xml = read_text(xml, "DCC")
    root = ET.fromstring(xml.encode("utf-8") if isinstance(xml, str) else xml)
    si = f"{{{SI_NS}}}"
    out: dict[str, dict[str, list]] = {}

    def fl(e: ET.Element | None) -> list[float]:
        return [] if e is None or not e.text else [float(x) for x in e.text.split()]

    for q in root.iter(f"{{{DCC_NS}}}quantity"):
        ref = q.get("refType")
        if not ref:
            continue
        blocks = [(e, "XMLList") for e in q.iter(f"{si}realListXMLList")] + [(e, "") for e in q.iter(f"{si}real")]
        hybrid = q.find(f"{si}hybrid") is not None
        for e, suffix in blocks:
            unc = e.find(f"{si}expandedUnc{suffix}")
            units = (e.findtext(f"{si}unit{suffix}") or "").split()
            doc = {"unit": units, "value": fl(e.find(f"{si}value{suffix}")),
                   "U": fl(None if unc is None else unc.find(f"{si}uncertainty{suffix}")),
                   "k": fl(None if unc is None else unc.find(f"{si}coverageFactor{suffix}")),
                   "p": fl(None if unc is None else unc.find(f"{si}coverageProbability{suffix}"))}
            key = f"{ref}@{units[0] if units else ''}" if hybrid else ref
            out.setdefault(key, doc)
    return out
