"""One job, three front ends, identical numbers (issue 16).

Every job of :mod:`senscal.jobs` that its command hands to the job layer
(``JOB_OPTIONS``) runs on a simulated recording

- through its command: ``senscal JOB FILE OPTIONS --json``;
- through ``senscal batch JOB FILE OPTIONS --json`` (a Dask worker process,
  on one shared local cluster);
- through the Python API: ``senscal.jobs.run(job, FILE, Options(...))``, with
  the options written as Python values, not parsed from words;

and the three JSON documents must be equal, every number to the last bit
(the same code on the same data: any difference is a front end adding,
dropping or converting something).
"""

from __future__ import annotations

import json
import math

import pytest

from senscal import jobs
from senscal._result import to_jsonable

# job -> (simulator words, recording, option words, API options, setup command or None).
# "{d}" is the test folder.  Linearity is left out: it needs several recordings (one per input level)
# in one run, so it is not a per-recording batch job.
CASES = {
    "fit": (["sine", "--out", "{d}/sine", "--seed", "1"], "sine/sine.csv", ["--freq", "12.5", "--harmonics", "2"],
            dict(freq=12.5, harmonics=2), None),
    "velocity": (["hydraulic", "--out", "{d}/hy", "--seed", "1"], "hy/hydraulic_01.csv",
                 ["--position", "position", "--velocity", "velocity"], dict(position="position", velocity="velocity"),
                 None),
    "response": (["centrifuge", "--out", "{d}/cf", "--seed", "1"], "cf/centrifuge_01.csv",
                 ["--output", "output", "--input-amplitude", "100", "--angle", "angle"],
                 dict(output="output", input_amplitude=100.0, angle="angle"), None),
    "shaft-calibrate": (["shaft", "--out", "{d}/sh", "--seed", "1"], "sh/shaft_cal.csv",
                        ["--angle", "angle", "--accel", "accel"], dict(angle="angle", accel="accel"), None),
    "shaft-compensate": (["shaft", "--out", "{d}/sh", "--seed", "1"], "sh/shaft_test.csv",
                         ["--model", "{d}/model.json", "--angle", "angle", "--accel", "accel", "--radius", "0.1"],
                         dict(model="{d}/model.json", angle="angle", accel="accel", radius=0.1),
                         ["shaft", "calibrate", "{d}/sh/shaft_cal.csv", "--angle", "angle", "--accel", "accel",
                          "--out", "{d}/model.json"]),
    "gfimu": (["gfimu", "--out", "{d}/gf", "--seed", "0", "--duration", "2"], "gf/gfimu.csv", ["--method", "kalman"],
              dict(method="kalman"), None),
    "drift": (["drift", "--out", "{d}/dr", "--seed", "1"], "dr/drift.csv",
              ["--preset", "redundant", "--channels", "ref,drift,thermal", "--trusted", "ref",
               "--covariate", "temperature"],
              dict(preset="redundant", channels=("ref", "drift", "thermal"), trusted=("ref",), covariate="temperature"),
              None),
    "triaxial-calibrate": (["magnetometer", "--out", "{d}/mg", "--motion", "sphere", "--seed", "1"],
                           "mg/magnetometer.csv", ["--channels", "x,y,z", "--field", "50000"],
                           dict(channels=("x", "y", "z"), field=50000.0), None),
    "triaxial-apply": (["magnetometer", "--out", "{d}/mg", "--motion", "sphere", "--seed", "1"],
                       "mg/magnetometer.csv", ["--params", "{d}/params.json", "--channels", "x,y,z"],
                       dict(params="{d}/params.json", channels=("x", "y", "z")),
                       ["triaxial", "calibrate", "{d}/mg/magnetometer.csv", "--channels", "x,y,z", "--field", "50000",
                        "--out", "{d}/params.json"]),
}


# Jobs whose command needs an output file per recording (--out): batch refuses them in one line.
NOT_BATCH = {"triaxial-apply": ["--out", "{d}/corrected.csv"]}


def _ready(job: str) -> str | None:
    """Why ``job`` cannot run through all three front ends yet (None when it can)."""
    import importlib

    from senscal.cli._manifest_data import COMMANDS

    try:
        jobs.options(job)
    except Exception as exc:  # noqa: BLE001 - a job module another engineer has not written yet
        return f"job module not there: {exc}"
    module = next((m for name, (m, _) in COMMANDS.items() if job == name or job.startswith(name + "-")), None)
    mod = importlib.import_module(f"senscal.cli.{module}")
    return None if job in getattr(mod, "JOB_OPTIONS", {}) else f"senscal.cli.{module} has no JOB_OPTIONS[{job!r}]"


def _fill(obj, d):
    if isinstance(obj, str):
        return obj.replace("{d}", str(d))
    if isinstance(obj, (list, tuple)):
        return type(obj)(_fill(v, d) for v in obj)
    if isinstance(obj, dict):
        return {k: _fill(v, d) for k, v in obj.items()}
    return obj


@pytest.fixture(scope="module")
def scheduler():
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=50) as cluster:
        yield cluster.scheduler_address


def _same(a, b, where="document"):
    """Assert two JSON documents are equal, floats to the bit; say where they differ."""
    assert type(a) is type(b) or {type(a), type(b)} <= {int, float}, f"{where}: {a!r} != {b!r}"
    if isinstance(a, dict):
        assert list(a) == list(b), f"{where}: keys {list(a)} != {list(b)}"
        for k in a:
            _same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), f"{where}: {len(a)} items != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), f"{where}: {a!r} != {b!r}"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


@pytest.mark.parametrize("job", list(CASES))
def test_cli_batch_and_api_give_identical_numbers(job, cli, tmp_path, scheduler):
    why = _ready(job)
    if why:
        pytest.skip(why)
    sim, rec, words, api, setup = _fill(CASES[job], tmp_path)
    r = cli("simulate", *sim)
    assert r.code == 0, r.err
    if setup:
        r = cli(*setup)
        assert r.code == 0, r.err
    path = str(tmp_path / rec)
    cmd = job.split("-", 1) if job.startswith(("shaft-", "triaxial-")) else [job]

    r = cli(*cmd, path, *words, *_fill(NOT_BATCH.get(job, []), tmp_path), "--json")
    assert r.code == 0, r.err
    via_cli = json.loads(r.out)

    r = cli("batch", job, path, *words, "--scheduler", scheduler, "--json")
    if job in NOT_BATCH:
        assert r.code == 2 and "per recording" in r.err and len(r.err.strip().splitlines()) == 1, r.err
    else:
        assert r.code == 0, r.err
        row = json.loads(r.out)["rows"][0]
        assert row["ok"], row["error"]
        _same(via_cli, row["result"], f"{job}: CLI vs batch")

    if api is None:  # options written out below from the job's own Options class
        pytest.skip(f"no Python options written for {job} in CASES")
    result = jobs.run(job, path, jobs.options(job, **api))
    assert isinstance(result, jobs.JobResult)
    via_api = json.loads(json.dumps(to_jsonable(result.to_dict())))

    if job in NOT_BATCH:  # the command names the file it wrote; the API wrote none
        via_cli.pop("out", None), via_api.pop("out", None)
    _same(via_cli, via_api, f"{job}: CLI vs API")
    # The registry stores result.quantities(): plain numbers with positive u, named as the command saves them.
    for q in result.quantities():
        assert math.isfinite(q.value) and q.uncertainty > 0


def test_the_comparison_can_fail():
    _same({"a": [1.0, 2.0]}, {"a": [1.0, 2.0]})
    for other in ({"a": [1.0, 2.0 + 2e-16 * 2]}, {"a": [1.0]}, {"b": [1.0, 2.0]}, {"a": [1.0, None]}):
        with pytest.raises(AssertionError):
            _same({"a": [1.0, 2.0]}, other)
