"""Every command on mutated inputs: no traceback, no internal error, no hang, one-line errors, inputs intact.

Each target's valid seed file (a recording of each format, or a side file of
each kind) is mutated by a seeded byte mutator (bit flips, cuts, insertions,
hostile tokens such as ``nan``, ``1e999``, ``[/bold]``, non-UTF-8 bytes,
deep nesting) and the command run in-process.  CI runs a fixed number of
cases per target; ``SENSCAL_FUZZ=long`` runs many more (nightly).
"""

from __future__ import annotations

import os
import zlib

import pytest

from _fuzz_harness import CASE_TIMEOUT_S, CASES_PER_TARGET, TALLY, check_seeds, dump_summary, fuzz_target

TARGETS = ["fit.csv", "fit.parquet", "fit.h5", "fit.tdms", "fit.npz", "fit-fs.parquet", "fit-fs.npz", "velocity",
           "response", "shaft calibrate", "shaft compensate --model", "triaxial calibrate",
           "triaxial apply --params", "gfimu", "gfimu --layout", "drift", "drift --model", "registry import",
           "fit-array"]


def test_corpus_covers_every_target_and_seeds_run(corpus, tmp_path):
    assert sorted(corpus) == sorted(TARGETS)
    assert check_seeds(list(corpus.values()), tmp_path) == []


@pytest.mark.parametrize("name", TARGETS)
def test_mutated_inputs(cli, corpus, tmp_path, name):
    before = len(TALLY.failures)
    fuzz_target(cli, corpus[name], CASES_PER_TARGET, zlib.crc32(name.encode()), tmp_path, TALLY, CASE_TIMEOUT_S)
    dump_summary(TALLY, os.environ.get("SENSCAL_FUZZ_REPORT"))  # kept up to date: a killed long run still reports
    failures = TALLY.failures[before:]
    assert not failures, f"{len(failures)} bad outcomes, first: " + "\n".join(failures[:5])
