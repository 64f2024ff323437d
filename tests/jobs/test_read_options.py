"""One set of reading options (``ReadOptions``) serves every job, its command and ``senscal batch``."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import math

import numpy as np
import pytest

from senscal import jobs
from senscal.io import Recording, write_recording
from senscal.jobs._base import ReadOptions, with_read_options

READ_FIELDS = [f.name for f in dataclasses.fields(ReadOptions)]


@pytest.mark.parametrize("job", jobs.names())
def test_every_job_reads_with_the_shared_options(job):
    module, _, cls_name = jobs.JOBS[job]
    cls = getattr(importlib.import_module(module), cls_name)
    assert issubclass(cls, ReadOptions)
    # Keyword construction (what tests, docs and batch use) takes every reading word.
    opts = cls(time_column="time", fs=250.0, names="a,b", time_unit="ms", skip_rows=2)
    got = (opts.time_column, opts.fs, opts.names, opts.time_unit, opts.skip_rows)
    assert got == ("time", 250.0, ("a", "b"), "ms", 2)
    # One spelling: the command line's "a, b" and the API's tuple are the same options.
    assert cls(names=" a, b") == cls(names=("a", "b"))


@pytest.mark.parametrize("job", jobs.names())
def test_every_batch_builder_names_the_reading_words(job):
    """``senscal batch`` refuses a word its builder does not name: the reading words must be named."""
    from senscal.cli._manifest_data import COMMANDS
    from senscal.cli.cmd_batch import _job_command

    module = _job_command(job)[1]
    assert module in {m for m, _ in COMMANDS.values()}
    builder = importlib.import_module(f"senscal.cli.{module}").JOB_OPTIONS[job]
    named = inspect.signature(builder).parameters
    assert all(f in named for f in READ_FIELDS), job


def test_the_wrapper_copies_the_words_given_and_keeps_the_rest():
    @dataclasses.dataclass(frozen=True)
    class Opts(ReadOptions):
        gain: float = 1.0

    @with_read_options
    def build(*, gain=1.0, **_):
        return Opts(gain=gain)

    assert list(inspect.signature(build).parameters)[:2] == ["gain", "time_column"]
    o = build(gain=2.0, fs=100.0, names="x", plot="p.png")
    assert (o.gain, o.fs, o.names, o.time_column) == (2.0, 100.0, ("x",), "t")
    assert build(gain=3.0) == Opts(gain=3.0)


def test_batch_passes_the_reading_words_through(tmp_path):
    from senscal.cli.cmd_batch import job_options

    f = tmp_path / "x.csv"
    f.write_text("1,2\n3,4\n")
    opts, strict = job_options("fit", str(f), ["--freq", "5", "--fs", "100", "--names", "a,b", "--time-column", "T"])
    assert (opts.freq, opts.fs, opts.names, opts.time_column, strict) == (5.0, 100.0, ("a", "b"), "T", False)


def test_a_time_unit_reaches_the_fit(tmp_path):
    """A job that had no time unit before the shared options: a time column in ms, declared by ``time_unit``."""
    t = np.arange(2000) / 1000.0
    rec = Recording(channels={"y": np.sin(2 * math.pi * 7.0 * t)}, t=t)
    path = write_recording(rec, tmp_path / "s.csv")
    ms = tmp_path / "ms.csv"
    lines = path.read_text().splitlines()
    ms.write_text("\n".join([lines[0]] + [f"{float(a) * 1e3!r},{b}" for a, b in (ln.split(",") for ln in lines[1:])]))
    in_s = jobs.run("fit", str(path), jobs.options("fit"))
    in_ms = jobs.run("fit", str(ms), jobs.options("fit", time_unit="ms"))
    assert in_ms.channels["y"].frequency == pytest.approx(in_s.channels["y"].frequency, rel=1e-9)
    assert in_s.channels["y"].frequency == pytest.approx(7.0, rel=1e-6)
