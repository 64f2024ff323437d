"""Linear Gaussian state-space engine: Kalman filter, RTS and fixed-lag smoothers.

>>> from senscal.kalman import StateSpaceModel, kalman_filter, rts_smoother
>>> model = StateSpaceModel(F, H, Q, R)          # doctest: +SKIP
>>> res = kalman_filter(model, y)                # y: (m, T), NaN = missing
>>> sm = rts_smoother(model, res)

Numba kernels, Joseph-form covariance updates, a steady-state gain path for
time-invariant models, many independent series at once (y of shape
(S, m, T)).
"""

from senscal.kalman.core import (KalmanResult, SmootherResult, fixed_lag_smoother, kalman_filter, log_likelihood,
                                 rts_smoother)
from senscal.kalman.model import StateSpaceModel

__all__ = ["StateSpaceModel", "KalmanResult", "SmootherResult", "kalman_filter", "rts_smoother",
           "fixed_lag_smoother", "log_likelihood"]
