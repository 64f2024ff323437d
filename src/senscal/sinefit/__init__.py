"""The sine-fit engine: three-parameter, four-parameter and multi-harmonic fits."""

from senscal.sinefit.core import SineFit, fit_sine, wrap_phase

__all__ = ["SineFit", "fit_sine", "wrap_phase"]
