"""Reading and writing recordings (CSV, Parquet, HDF5, TDMS, NPZ)."""

from senscal.io.guard import check_output, note_input, protect_inputs
from senscal.io.readers import FORMATS, read_recording, write_recording
from senscal.io.recording import Recording, check_finite, check_time

__all__ = ["Recording", "read_recording", "write_recording", "check_finite", "check_time", "FORMATS",
           "check_output", "note_input", "protect_inputs"]
