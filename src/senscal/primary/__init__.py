"""Primary vibration calibration by laser interferometry (ISO 16063-11, method 3: homodyne quadrature).

Pure numeric engine: the Heydemann correction of the quadrature signals
(:func:`heydemann_fit`, :func:`corrected_phase`), and the sine-approximation
calibration of one frequency point (:func:`calibrate_point`), with fringe counting
(:func:`fringe_count`, ISO 16063-11 method 1) as its magnitude cross-check.
"""

from senscal.primary.core import (FringeCount, HeydemannFit, PrimaryPoint, calibrate_point, corrected_phase,
                                  fringe_count, heydemann_fit)

__all__ = ["FringeCount", "HeydemannFit", "PrimaryPoint", "calibrate_point", "corrected_phase", "fringe_count",
           "heydemann_fit"]
