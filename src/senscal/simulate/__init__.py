"""Physical simulators that write realistic recordings with known truth.

One module per job; each exposes a pure function returning
``(Recording or list of Recording, truth dict)`` and the CLI writes them with
:func:`write_truth` beside the recordings.
"""

from senscal.simulate.common import write_truth
from senscal.simulate.sine import simulate_sine

__all__ = ["write_truth", "simulate_sine"]
