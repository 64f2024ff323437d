"""Reading and writing recordings (CSV, Parquet, HDF5, TDMS, NPZ).

Names are loaded on first use (PEP 562), so ``senscal.io.guard`` and the
command line start without importing pandas, h5py and pyarrow.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from senscal._lazy import lazy_attributes

_LAZY = {
    "check_output": "senscal.io.guard", "note_input": "senscal.io.guard", "protect_inputs": "senscal.io.guard",
    "FORMATS": "senscal.io.readers", "read_recording": "senscal.io.readers", "write_recording": "senscal.io.readers",
    "Recording": "senscal.io.recording", "check_finite": "senscal.io.recording", "check_time": "senscal.io.recording",
}

__all__ = ["Recording", "read_recording", "write_recording", "check_finite", "check_time", "FORMATS",
           "check_output", "note_input", "protect_inputs"]

if TYPE_CHECKING:  # pragma: no cover
    from senscal.io.guard import check_output, note_input, protect_inputs
    from senscal.io.readers import FORMATS, read_recording, write_recording
    from senscal.io.recording import Recording, check_finite, check_time


__getattr__, __dir__ = lazy_attributes(__name__, globals(), _LAZY)
