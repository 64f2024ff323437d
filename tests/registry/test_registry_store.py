"""The registry store on SQLite and PostgreSQL: records, supersedes, export/import, errors."""

from __future__ import annotations

import hashlib
import json
import socket
from datetime import datetime, timedelta, timezone

import pytest
import sqlalchemy as sa

from senscal.errors import DataError, InputError, TooFewSamplesError
from senscal.registry import (DuplicateSensorError, Quantity, UnknownQuantityError, UnknownSensorError,
                              open_registry)

Q = "sensitivity"
UNIT = "V/(m/s^2)"


def _q(value, u=1e-5):
    return [Quantity(Q, value, u, UNIT, 2.0)]


def test_sensors_and_records_round_trip(db_url, tmp_path):
    data = tmp_path / "input.csv"
    data.write_bytes(b"t,a\n0,1\n")
    with open_registry(db_url) as reg:
        s = reg.add_sensor("A1", "accelerometer", model="4371", nominal={Q: {"value": 0.01, "unit": UNIT}})
        assert s.nominal[Q]["value"] == 0.01 and s.created_at.tzinfo is not None
        rec = reg.record("A1", _q(0.0101), performed_at="2024-03-01T09:30:00.123456+01:00", job="fit",
                         method="sine-fit", conditions={"temperature_C": 23.1}, result={"x": [1.5, None]},
                         input_files=[data], operator="ana", note="n1")
    with open_registry(db_url) as reg:  # a second open finds the schema at head
        back = reg.calibration(rec.uid)
    assert back == rec
    # The original offset and microseconds survive storage.
    assert back.performed_at.utcoffset() == timedelta(hours=1) and back.performed_at.microsecond == 123456
    assert back.input_files[0]["sha256"] == hashlib.sha256(data.read_bytes()).hexdigest()
    assert back.senscal_version and back.conditions == {"temperature_C": 23.1} and back.result == {"x": [1.5, None]}
    assert back.quantities[0] == Quantity(Q, 0.0101, 1e-5, UNIT, 2.0)


def test_errors_unknown_and_duplicate_serial(db_url):
    with open_registry(db_url) as reg:
        reg.add_sensor("A1", "accelerometer")
        with pytest.raises(DuplicateSensorError, match="already registered"):
            reg.add_sensor("A1", "magnetometer")
        with pytest.raises(UnknownSensorError, match="unknown sensor serial 'ZZ'"):
            reg.record("ZZ", _q(1.0))
        with pytest.raises(UnknownSensorError):
            reg.history("ZZ")
        reg.record("NEW", _q(1.0), create_kind="accelerometer")
        assert reg.sensor("NEW").kind == "accelerometer"
        with pytest.raises(UnknownQuantityError, match="recorded quantities: sensitivity"):
            reg.history("NEW", "phase")
        with pytest.raises(TooFewSamplesError, match="1 record .*at least two"):
            reg.drift("NEW", Q, tolerance=0.01)
        with pytest.raises(DataError, match="positive"):
            Quantity(Q, 1.0, 0.0, UNIT)
        with pytest.raises(InputError, match="control characters"):
            Quantity("a\x00b", 1.0, 0.1, UNIT)
        with pytest.raises(InputError, match="lone surrogate"):
            reg.add_sensor("bad\ud800", "accelerometer")
        with pytest.raises(InputError, match="note .*lone surrogate"):
            reg.record("NEW", _q(1.0), note="x\udcff")
        reg.record("NEW", _q(1.0), note="line 1\nline 2\ttab")


def test_records_are_append_only_and_corrections_supersede(db_url):
    with open_registry(db_url) as reg:
        reg.add_sensor("A1", "accelerometer")
        reg.add_sensor("B2", "accelerometer")
        first = reg.record("A1", _q(0.0100), performed_at="2020-01-01")
        wrong = reg.record("A1", _q(0.0200), performed_at="2021-01-01", note="typo")
        fixed = reg.record("A1", _q(0.0102), performed_at="2021-01-01", supersedes=wrong.uid[:8], note="fixed")
        other = reg.record("B2", _q(0.0100), performed_at="2021-01-01")
        with pytest.raises(InputError, match="another sensor"):
            reg.record("A1", _q(0.0101), supersedes=other.uid)
        with pytest.raises(InputError, match="too short"):
            reg.record("A1", _q(0.0101), supersedes="ab")
        current = [p.uid for p in reg.history("A1", Q)]
        everything = {p.uid: p for p in reg.history("A1", Q, include_superseded=True)}
        assert current == [first.uid, fixed.uid]
        assert everything[wrong.uid].superseded_by == fixed.uid
        # The database itself refuses edits and deletions of evidence.
        for stmt in ("UPDATE quantities SET value = 1", "DELETE FROM calibrations"):
            with pytest.raises(sa.exc.DBAPIError, match="append-only"):
                with reg.engine.begin() as conn:
                    conn.execute(sa.text(stmt))
        assert reg.drift("A1", Q).fit.n_records == 2


def test_known_drift_and_due_date_through_the_store(db_url):
    """Six yearly certificates of a sensor drifting +0.4 %/yr: rate within its uncertainty, due date consistent."""
    import numpy as np

    rng = np.random.default_rng(3)
    v0, drift, u = 0.0100, 0.004 * 0.0100, 2e-6
    start = datetime(2018, 5, 1, tzinfo=timezone.utc)
    with open_registry(db_url) as reg:
        reg.add_sensor("D1", "accelerometer")
        for i in range(6):
            when = start + timedelta(days=365.25 * i + rng.uniform(-20, 20))
            years = (when - start).total_seconds() / 86400 / 365.25
            reg.record("D1", _q(v0 + drift * years + rng.normal(0, u), u), performed_at=when)
        rep = reg.drift("D1", Q, tolerance=0.03, nominal=v0)
    assert abs(rep.drift_per_year - drift) < 4 * rep.u_drift_per_year
    assert rep.significant
    # Due before the noiseless crossing (tolerance / drift = 7.5 years after the start) but after the last record.
    t_due = (rep.due_date - start).total_seconds() / 86400 / 365.25
    assert rep.last_date < rep.due_date and t_due < 0.03 / 0.004
    value, u_line = rep.fit.predict(rep.due.t_due)
    assert abs(value - v0) + 2 * u_line == pytest.approx(0.03 * v0, rel=1e-4)


def test_export_then_import_into_empty_database_is_identical(db_url, tmp_path):
    with open_registry(db_url) as reg:
        reg.add_sensor("A1", "accelerometer", manufacturer="ACME", notes="lab 2", nominal={Q: {"value": 0.01}})
        reg.add_sensor("M7", "magnetometer")
        a = reg.record("A1", _q(0.0100), performed_at="2019-06-01T08:00-04:00", result={"deep": {"v": 1 / 3}})
        reg.record("A1", _q(0.0103), performed_at="2020-06-01", supersedes=a.uid)
        reg.record("M7", [Quantity("hard_iron_x", 1.2e-6, 3e-8, "T", 1.0), Quantity("scale_x", 1.0001, 1e-5, "", 2)],
                   performed_at="2022-02-02T02:02:02.5+05:30")
        doc = reg.export()
    text = json.dumps(doc)
    target = f"sqlite:///{tmp_path / 'copy.sqlite'}"
    with open_registry(target) as copy:
        assert copy.import_(json.loads(text)) == {"sensors": 2, "calibrations": 3, "skipped": 0}
        assert json.dumps(copy.export()) == text
        assert copy.import_(json.loads(text)) == {"sensors": 0, "calibrations": 0, "skipped": 3}
        assert json.dumps(copy.export()) == text


def test_bad_urls_give_one_line_errors_without_password(tmp_path):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cases = [
        (f"postgresql://lab:Secr3tPW@127.0.0.1:{port}/reg", "cannot reach"),
        ("postgresql://lab:Secr3tPW@@host:notaport/reg", "malformed database URL"),
        ("nosuchdb://lab:Secr3tPW@host/reg", "unknown database dialect"),
    ]
    for url, expected in cases:
        with pytest.raises(InputError, match=expected) as exc:
            open_registry(url)
        msg = str(exc.value)
        assert "Secr3tPW" not in msg and "***" in msg and "\n" not in msg


def test_wrong_password_on_real_server_is_masked(pg_url):
    from sqlalchemy.engine import make_url

    bad = make_url(pg_url).set(password="Wr0ngPassw0rd")
    with pytest.raises(InputError, match="cannot reach") as exc:
        open_registry(bad.render_as_string(hide_password=False))
    assert "Wr0ngPassw0rd" not in str(exc.value) and str(make_url(pg_url).password) not in str(exc.value)


def test_schema_from_a_newer_senscal_is_a_clear_error(tmp_path):
    url = f"sqlite:///{tmp_path / 'r.sqlite'}"
    open_registry(url).close()
    engine = sa.create_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("UPDATE alembic_version SET version_num = '0999'"))
    engine.dispose()
    with pytest.raises(InputError, match="schema revision '0999'.*upgrade senscal"):
        open_registry(url)


#: Characters the registry refuses in a name (bidi overrides, zero-width, controls, separators, private use,
#: unassigned: registry.store), so the round-trip property draws names it accepts.
CONTROL_OR_FORMAT = ("Cs", "Cf", "Cc", "Zl", "Zp", "Co", "Cn")


def test_any_record_reads_back_exactly(db_url):
    """Property: values, uncertainties, offsets and microseconds survive the database bit for bit."""
    from hypothesis import given, settings, strategies as st

    reg = open_registry(db_url)
    reg.add_sensor("P", "accelerometer")
    calls: list[None] = []
    finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
    positive = st.floats(min_value=1e-300, max_value=1e300, allow_nan=False)

    @settings(max_examples=30, deadline=None)
    @given(value=finite, u=positive, k=st.sampled_from([1.0, 2.0, 2.576, 3.0]),
           when=st.datetimes(min_value=datetime(1950, 1, 1), max_value=datetime(2100, 1, 1)),
           offset_min=st.integers(-12 * 60, 14 * 60), name=st.text(st.characters(min_codepoint=32, exclude_categories=CONTROL_OR_FORMAT), min_size=1,
                        max_size=30).filter(str.strip))
    def check(value, u, k, when, offset_min, name):
        performed = when.replace(tzinfo=timezone(timedelta(minutes=offset_min)))
        # Hypothesis replays examples (and shrinks to the same one); a replay would be the same record, which
        # the registry rightly keeps once, so each call's result carries its own serial number.
        calls.append(None)
        rec = reg.record("P", [Quantity(name, value, u, "V", k)], performed_at=performed,
                         result={"v": value, "call": len(calls)})
        assert not rec.already_recorded
        back = reg.calibration(rec.uid)
        assert back == rec
        assert back.performed_at.utcoffset() == timedelta(minutes=offset_min)
        assert back.performed_at.replace(tzinfo=None) == when

    try:
        check()
    finally:
        reg.close()


def test_sqlite_reader_does_not_block_a_writer(tmp_path):
    from senscal.registry import db

    url = f"sqlite:///{tmp_path / 'wal.sqlite'}"
    reader, writer = open_registry(url), open_registry(url)
    writer.add_sensor("A1", "accelerometer")
    with db.read_connection(reader.engine) as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        n0 = conn.execute(sa.text("SELECT count(*) FROM calibrations")).scalar()  # holds a read snapshot
        writer.record("A1", _q(0.01))  # would wait for the busy timeout if readers took the write lock
        assert conn.execute(sa.text("SELECT count(*) FROM calibrations")).scalar() == n0  # snapshot isolation
    assert len(reader.calibrations("A1")) == 1
    reader.close()
    writer.close()
