"""One function per user job: typed options in, a frozen result out.

The CLI, ``senscal batch``, the demo and the registry all call these; the
command-line front end only parses arguments, calls a job and prints.

Every job is ``job(source, options) -> Result`` where ``source`` is a path
or a :class:`~senscal.io.Recording` (multi-file jobs take a sequence), and
``options`` a frozen dataclass with defaults (``FitOptions()`` ...). The
result is a :class:`JobResult`: ``to_dict()`` (the ``--json`` document),
``quantities()`` (what the registry stores), ``to_dataframe()``, and
``warnings`` (named warnings: ``coloured-noise: ...``).

Examples
--------
>>> from senscal import jobs                                          # doctest: +SKIP
>>> res = jobs.run("fit", "sine.csv", jobs.options("fit", freq=80.0))  # doctest: +SKIP
>>> res.quantities()                                                  # doctest: +SKIP
"""

from __future__ import annotations

import importlib
from typing import Any

from senscal.errors import InputError
from senscal.jobs._base import JobResult, Quantity

__all__ = ["JobResult", "Quantity", "JOBS", "get", "options", "run", "names"]

# job name -> (module, function, options class). Modules import lazily so that
# ``import senscal.jobs`` stays cheap (the CLI's start-up time depends on it).
JOBS: dict[str, tuple[str, str, str]] = {}


def register(name: str, module: str, function: str, options_class: str) -> None:
    """Declare a job (called at import of this package, below)."""
    JOBS[name] = (module, function, options_class)


def names() -> list[str]:
    """The job names, sorted."""
    return sorted(JOBS)


def _entry(name: str) -> tuple[Any, type]:
    try:
        module, function, opts = JOBS[name]
    except KeyError:
        raise InputError(f"unknown job {name!r}; jobs are: {', '.join(names())}") from None
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name != module:
            raise  # a missing dependency inside the job module is a real error
        raise InputError(f"job {name!r} is not available in this version of senscal ({module} is missing)") from None
    return getattr(mod, function), getattr(mod, opts)


def get(name: str):
    """The job function called ``name``."""
    return _entry(name)[0]


def options(name: str, **values: Any):
    """The options dataclass of job ``name`` built from keyword values."""
    cls = _entry(name)[1]
    try:
        return cls(**values)
    except TypeError as exc:
        raise InputError(f"job {name!r}: {exc}") from None


def run(name: str, source: Any, opts: Any = None) -> JobResult:
    """Run job ``name`` on ``source`` with ``opts`` (defaults when None)."""
    fn, cls = _entry(name)
    return fn(source, cls() if opts is None else opts)


# The job table. Each job module defines its function and options class.
for _name, _module, _function, _opts in (
    ("fit", "senscal.jobs.fit", "fit", "FitOptions"),
    ("velocity", "senscal.jobs.vibration", "velocity", "VelocityOptions"),
    ("response", "senscal.jobs.vibration", "response", "ResponseOptions"),
    ("linearity", "senscal.jobs.vibration", "linearity", "LinearityOptions"),
    ("shaft-calibrate", "senscal.jobs.shaft", "shaft_calibrate", "ShaftCalibrateOptions"),
    ("shaft-compensate", "senscal.jobs.shaft", "shaft_compensate", "ShaftCompensateOptions"),
    ("gfimu", "senscal.jobs.gfimu", "gfimu", "GfimuOptions"),
    ("drift", "senscal.jobs.drift", "drift", "DriftOptions"),
    ("triaxial-calibrate", "senscal.jobs.triaxial", "triaxial_calibrate", "TriaxialCalibrateOptions"),
    ("triaxial-apply", "senscal.jobs.triaxial", "triaxial_apply", "TriaxialApplyOptions"),
    ("imu-calibrate", "senscal.jobs.imu", "imu_calibrate", "ImuOptions"),
    ("imu-apply", "senscal.jobs.imu", "imu_apply", "ImuApplyOptions"),
    ("primary", "senscal.jobs.primary", "primary", "PrimaryOptions"),
    ("shock", "senscal.jobs.shock", "shock", "ShockOptions"),
):
    register(_name, _module, _function, _opts)
del _name, _module, _function, _opts
