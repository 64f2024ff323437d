"""Primary vibration calibration by laser interferometry (ISO 16063-11, method 3: homodyne quadrature).

Pure numeric engine: the Heydemann correction of the quadrature signals
(:func:`heydemann_fit`, :func:`corrected_phase`), and the sine-approximation
calibration of one frequency point (:func:`calibrate_point`).
"""

from senscal.primary.core import (HeydemannFit, PrimaryPoint, calibrate_point, corrected_phase, heydemann_fit)

__all__ = ["HeydemannFit", "PrimaryPoint", "calibrate_point", "corrected_phase", "heydemann_fit"]
