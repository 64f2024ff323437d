"""QA: ``senscal.load_calibration`` on damaged and hand-edited files: a SenscalError naming the file, never more.

Valid files of each type (JSON and HDF5) are mutated structurally
(hypothesis: fields deleted, replaced by null, lists, mappings, NaN, inf,
negative or huge numbers, unknown keys added).  The loader must return the
typed calibration or raise a :class:`senscal.errors.SenscalError` subclass
with a one-line message that names the file.  It must never hand back a
calibration holding a NaN, an inf or a negative uncertainty: senscal never
writes one, so a file holding one is damaged.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from senscal import load_calibration
from senscal.errors import FileFormatError, SenscalError
from senscal.persist import write_document

DATA = Path(__file__).parents[1] / "calibration" / "data"
LONG = __import__("os").environ.get("SENSCAL_FUZZ", "").lower() == "long"

HOSTILE = [None, True, 0, -1, -1.0, 1e308, float("nan"), float("inf"), "", "abc", [], {}, [[1, 2], [3]],
           [1.0, 2.0, 3.0], {"a": 1}, 99, "senscal.x"]


@pytest.fixture(scope="module")
def documents(tmp_path_factory):
    """Version-2 documents of each type: the stored version-1 files loaded and saved again."""
    from senscal.vibration.response import save_response

    d = tmp_path_factory.mktemp("cal")
    out = {}
    for name, src in (("shaft", "shaft_model_v1.json"), ("triaxial", "triaxial_params_v1.json"),
                      ("response", "response_v1.json")):
        obj = load_calibration(DATA / src)
        p = d / f"{name}.json"
        save_response(obj, p) if name == "response" else obj.save(p)
        out[name] = json.loads(p.read_text())
    return out


def _paths(doc, prefix=()):
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    out = []
    for k, v in items:
        out.append(prefix + (k,))
        out.extend(_paths(v, prefix + (k,)))
    return out


def _non_finite(obj, depth=0) -> bool:
    """A NaN or inf anywhere in a loaded calibration (dataclass fields, arrays, lists, mappings)."""
    if depth > 5:
        return False
    if isinstance(obj, float):
        return not math.isfinite(obj)
    if isinstance(obj, np.ndarray):
        return obj.dtype.kind == "f" and not np.all(np.isfinite(obj))
    if hasattr(obj, "__dataclass_fields__"):
        return any(_non_finite(getattr(obj, f), depth + 1) for f in obj.__dataclass_fields__)
    if isinstance(obj, (list, tuple)):
        return any(_non_finite(x, depth + 1) for x in obj)
    if isinstance(obj, dict):
        return any(_non_finite(x, depth + 1) for x in obj.values())
    return False


@settings(max_examples=300 if LONG else 30, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data(), name=st.sampled_from(["shaft", "triaxial", "response"]), suffix=st.sampled_from([".json", ".h5"]))
def test_mutated_calibration_files(documents, tmp_path_factory, data, name, suffix):
    doc = json.loads(json.dumps(documents[name]))
    for _ in range(data.draw(st.integers(1, 2))):
        path = data.draw(st.sampled_from(_paths(doc)))
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        if data.draw(st.booleans()) and isinstance(parent, dict):
            del parent[path[-1]]
        else:
            parent[path[-1]] = data.draw(st.sampled_from(HOSTILE))
    p = tmp_path_factory.mktemp("m") / f"{name}{suffix}"
    try:
        write_document(doc, p)
    except SenscalError:
        return  # a tree HDF5 cannot hold (ragged lists): nothing to load
    try:
        obj = load_calibration(p)
    except Exception as exc:  # noqa: BLE001 - the point: which exception
        assert isinstance(exc, SenscalError), f"{type(exc).__name__}: {exc}"
        assert "\n" not in str(exc) and p.name in str(exc), str(exc)
        return
    assert not _non_finite(obj), obj


@pytest.mark.parametrize("edit, match", [
    # Loaded, then corrected data came out NaN (a hand-edited 'NaN').
    (lambda d: d.update(amplitude=float("nan")), "non-finite number at amplitude"),
    # Loaded with a negative standard uncertainty.
    (lambda d: d.update(u_amplitude=-1.0), "negative uncertainty at u_amplitude"),
])
def test_damaged_shaft_model(documents, tmp_path, edit, match):
    doc = dict(documents["shaft"])
    edit(doc)
    for suffix in (".json", ".h5"):
        p = tmp_path / f"m{suffix}"
        write_document(doc, p) if suffix == ".h5" else p.write_text(json.dumps(doc))
        with pytest.raises(FileFormatError, match=match):
            load_calibration(p)


def test_wrong_field_type_names_the_file(documents, tmp_path):
    # Was TypeError ('int' object is not iterable) from the shaft model's reader (tuple(warnings)).
    doc = dict(documents["shaft"])
    doc["warnings"] = 5
    p = tmp_path / "m.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(FileFormatError, match="m.json"):
        load_calibration(p)


def test_drift_state_is_named_for_what_it_is(tmp_path):
    p = tmp_path / "state.json"
    p.write_text(json.dumps({"format_version": 1, "kind": "senscal drift tracker state", "setup": {}}))
    with pytest.raises(FileFormatError, match="it is a drift tracker state"):
        load_calibration(p)



@pytest.mark.parametrize("as_of", ["2026-13-45", "yesterday", "", "2026-01-05T25:00", "99999-01-01", "nan",
                                   "2026-01-05T10:00+25:00"])
def test_registry_due_malformed_as_of(cli, tmp_path, as_of):
    # --as-of is checked before the database is opened: no registry is created or touched.
    db = tmp_path / "r.sqlite"
    r = cli("registry", "due", "SIM-001", "--quantity", "sensitivity", "--tolerance", "1%", "--db", db,
            "--as-of", as_of)
    assert r.code == 2 and "Traceback" not in r.err, r.err
    assert len(r.err.strip().splitlines()) == 1 and "--as-of" in r.err, r.err
    assert not db.exists()
