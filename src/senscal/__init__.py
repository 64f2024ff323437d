"""senscal: calibrate sensors and correct their errors.

Jobs live in sub-packages (``vibration``, ``shaft``, ``gfimu``, ``drift``,
``triaxial``) built on shared engines (``sinefit``, ``kalman``) and one
recording type (:class:`senscal.io.Recording`).
"""

from importlib.metadata import PackageNotFoundError, version as _version

from senscal import errors
from senscal.io import Recording, read_recording, write_recording
from senscal.sinefit import SineFit, fit_sine

try:
    __version__ = _version("senscal")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0+src"

__all__ = ["Recording", "read_recording", "write_recording", "fit_sine", "SineFit", "errors", "__version__"]
