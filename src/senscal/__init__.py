"""senscal: calibrate sensors and correct their errors.

Jobs live in sub-packages (``vibration``, ``shaft``, ``gfimu``, ``drift``,
``triaxial``) built on shared engines (``sinefit``, ``kalman``) and one
recording type (:class:`senscal.io.Recording`).  The top-level names load on
first use, so ``import senscal`` (and the command line) start fast.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from senscal._lazy import lazy_attributes

from senscal import errors

_LAZY = {
    "Recording": "senscal.io", "read_recording": "senscal.io", "write_recording": "senscal.io",
    "fit_sine": "senscal.sinefit", "SineFit": "senscal.sinefit",
    "load_calibration": "senscal.persist",
}

__all__ = ["Recording", "read_recording", "write_recording", "fit_sine", "SineFit", "load_calibration", "errors",
           "__version__"]

if TYPE_CHECKING:  # pragma: no cover
    from senscal.io import Recording, read_recording, write_recording
    from senscal.persist import load_calibration
    from senscal.sinefit import SineFit, fit_sine


_lazy_getattr, __dir__ = lazy_attributes(__name__, globals(), _LAZY)


def __getattr__(name: str):
    # The version is looked up on first use: importlib.metadata costs every command ~50 ms at start-up.
    if name == "__version__":
        from importlib.metadata import PackageNotFoundError, version

        try:
            value = version("senscal")
        except PackageNotFoundError:  # running from a source tree
            value = "0.0.0+src"
        globals()["__version__"] = value
        return value
    return _lazy_getattr(name)
