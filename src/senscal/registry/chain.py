"""Hash chain over the calibration records: tamper evidence for the registry.

Every record carries ``chain_hash = sha256(previous chain_hash || content)``
where ``content`` is a canonical JSON encoding of everything the record says
(its sensor's serial and kind, dates, quantities, result, input-file
fingerprints, ...). The records form one chain per registry in insertion
order, and the table ``registry_chain`` holds the number of records and the
newest hash (the head). Changing, deleting or inserting a record anywhere
(with the database's triggers dropped, or in a copy of the file) breaks the
chain at that record; deleting the newest records also needs the head row
rewritten. Someone who recomputes the whole chain after an edit is not
detected: the chain holds no secret. Compare the head that ``senscal
registry verify`` prints with one kept elsewhere (a certificate, a lab book)
to close that gap.

Pure functions of plain values: the database work is in
:mod:`senscal.registry.store`.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any, Iterable, Mapping, Sequence

__all__ = ["GENESIS", "CONTENT_VERSION", "canonical_content", "link", "ChainReport", "sensor_digest"]

#: The "previous hash" of the first record.
GENESIS = "0" * 64
#: Version of the canonical encoding (part of the hashed content, so a future
#: encoding cannot be confused with this one).
CONTENT_VERSION = 1


def _utc_iso(dt: datetime | None) -> str | None:
    if dt is None:
        return None
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=timezone.utc)
    return dt.astimezone(timezone.utc).isoformat()


def canonical_content(record: Mapping[str, Any], serial: str | None, kind: str | None,
                      quantities: Iterable[Sequence[Any]]) -> bytes:
    """The bytes a record's hash covers.

    Parameters
    ----------
    record : mapping
        Stored columns of the calibration: ``uid, performed_at, utc_offset_s,
        recorded_at, job, method, conditions, result, certificate,
        input_files, senscal_version, operator, note, supersedes``
        (datetimes timezone-aware or naive UTC); optional ``sensor_digest``
        and ``standards`` (pairs of a standard's ident and the SHA-256 of its
        row's content), hashed only when present.
    serial, kind : str or None
        The sensor the record belongs to (None when its sensor row is missing).
    quantities : iterable of (name, value, uncertainty, unit, k)
        Order does not matter (sorted by name here).

    Returns
    -------
    bytes
        UTF-8 JSON with sorted keys and no whitespace; floats as Python's
        shortest round-trip representation, so values read back from the
        database hash exactly as they were written.
    """
    doc = {
        "v": CONTENT_VERSION,
        "serial": serial, "kind": kind,
        "uid": record["uid"],
        "performed_at": _utc_iso(record["performed_at"]), "utc_offset_s": int(record["utc_offset_s"]),
        "recorded_at": _utc_iso(record["recorded_at"]),
        "job": record["job"], "method": record["method"],
        "conditions": record["conditions"] or {}, "result": record["result"],
        "certificate": record["certificate"], "input_files": list(record["input_files"] or ()),
        "senscal_version": record["senscal_version"], "operator": record["operator"], "note": record["note"],
        "supersedes": record["supersedes"],
        "quantities": sorted([str(q[0]), float(q[1]), float(q[2]), str(q[3]), float(q[4])] for q in quantities),
    }
    digest = record.get("sensor_digest")
    if digest is not None:
        # Records since schema 0003 cover their sensor's metadata too; older ones hash as they always did.
        doc["sensor_digest"] = digest
    used = record.get("standards")
    if used:
        # Records that name reference standards (schema 0004) cover each one's ident and content digest.
        doc["standards"] = sorted([str(i), str(h)] for i, h in used)
    return json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=True).encode("utf-8")


def sensor_digest(sensor: Mapping[str, Any]) -> str:
    """SHA-256 (hex) of a sensor's metadata: serial, kind, model, manufacturer, nominal values, notes, created_at.

    Stored in each record (schema 0003) and so covered by its chain hash:
    ``registry verify`` recomputes it from the sensor as it is now.
    """
    doc = {k: sensor.get(k) for k in ("serial", "kind", "model", "manufacturer", "nominal", "notes")}
    doc["created_at"] = _utc_iso(sensor.get("created_at"))
    return hashlib.sha256(json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                                     allow_nan=True).encode("utf-8")).hexdigest()


def link(previous: str, content: bytes) -> str:
    """``sha256(previous || content)`` as 64 hex digits."""
    return hashlib.sha256(previous.encode("ascii") + content).hexdigest()


@dataclass(frozen=True)
class ChainReport:
    """Result of recomputing a registry's hash chain.

    Attributes
    ----------
    intact : bool
        Every record's hash recomputes and the head matches the last record.
    n_records : int
        Calibration records found.
    head : str or None
        Hash of the newest record as recomputed (None for an empty registry).
    first_broken : str or None
        uid of the first record whose stored hash does not recompute.
    problems : tuple of str
        One sentence per finding, first the first broken record.
    n_standards : int
        Reference-standard rows found (their own chain is checked too, schema 0004).
    """

    intact: bool
    n_records: int
    head: str | None
    first_broken: str | None
    problems: tuple[str, ...]
    n_standards: int = 0
