"""Sine fits of arrays too large for memory, chunk by chunk on Dask.

The time axis of every chunk is whole (a fit needs the full record); the
channel axis is split, so 10,000 channels stream through the workers a chunk
at a time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import FileFormatError, InputError

__all__ = ["ArrayFit", "SUMMARY_FIELDS", "fit_sine_dask", "fit_hdf5_dataset"]

SUMMARY_FIELDS = ("frequency", "amplitude", "phase", "offset", "u_frequency", "u_amplitude", "u_phase",
                  "u_offset", "residual_rms", "snr_db")


@dataclass(frozen=True)
class ArrayFit(ResultMixin):
    """Per-channel sine-fit summaries of a large array (SI units, phase in rad).

    Every attribute of :data:`SUMMARY_FIELDS` is an array of shape (n_channels,).
    """

    frequency: np.ndarray
    amplitude: np.ndarray
    phase: np.ndarray
    offset: np.ndarray
    u_frequency: np.ndarray
    u_amplitude: np.ndarray
    u_phase: np.ndarray
    u_offset: np.ndarray
    residual_rms: np.ndarray
    snr_db: np.ndarray
    n_samples: int

    @property
    def n_channels(self) -> int:
        return int(self.amplitude.shape[0])


def _summaries(block: np.ndarray, t, fs, freq, harmonics) -> np.ndarray:
    from senscal.sinefit import fit_sine

    block = np.asarray(block, dtype=np.float64)
    if freq is not None:
        fit = fit_sine(block, t, fs=fs, freq=freq, harmonics=harmonics)
        return np.stack([np.atleast_1d(getattr(fit, f)) for f in SUMMARY_FIELDS], axis=1)
    rows = []
    for i in range(block.shape[0]):
        fit = fit_sine(block[i], t, fs=fs, harmonics=harmonics)
        rows.append([float(getattr(fit, f)) for f in SUMMARY_FIELDS])
    return np.asarray(rows).reshape(block.shape[0], len(SUMMARY_FIELDS))


def _to_result(table: np.ndarray, n: int) -> ArrayFit:
    return ArrayFit(**{f: table[:, j] for j, f in enumerate(SUMMARY_FIELDS)}, n_samples=n)


def fit_sine_dask(y, t=None, *, fs: float | None = None, freq: float | None = None, harmonics: int = 1,
                  chunk_channels: int = 256) -> ArrayFit:
    """Sine fit of every row of a (dask) array of shape (n_channels, N).

    Parameters
    ----------
    y : dask.array.Array or array_like, shape (n_channels, N)
        Channels on a shared time base; rechunked to whole rows.
    t, fs, freq, harmonics
        As for :func:`senscal.fit_sine`.
    chunk_channels : int
        Channels per task.

    Returns
    -------
    ArrayFit
        Computed with the current Dask scheduler (a ``distributed.Client`` if
        one is active).
    """
    import dask.array as da

    y = da.asarray(y)
    if y.ndim != 2:
        raise InputError(f"expected an array of shape (n_channels, n_samples), got {y.shape}")
    y = y.rechunk({0: chunk_channels, 1: -1})
    out = y.map_blocks(_summaries, t, fs, freq, harmonics, dtype=np.float64,
                       chunks=(y.chunks[0], (len(SUMMARY_FIELDS),)))
    return _to_result(out.compute(), int(y.shape[1]))


def _fit_hdf5_rows(path: str, dataset: str, c0: int, c1: int, t, fs, freq, harmonics) -> np.ndarray:
    import h5py

    with h5py.File(path, "r") as fh:
        block = fh[dataset][c0:c1]
    return _summaries(block, t, fs, freq, harmonics)


def fit_hdf5_dataset(path: str | Path, dataset: str, *, fs: float | None = None, time_dataset: str | None = None,
                     freq: float | None = None, harmonics: int = 1, chunk_channels: int = 256,
                     progress: Any = None) -> ArrayFit:
    """Fit every row of a 2-D HDF5 dataset (channels x samples) without loading it whole.

    Each task opens the file itself and reads only its rows, so this runs on a
    ``distributed`` cluster as well as on threads.  ``progress`` is called
    with the number of channels done as chunks complete.
    """
    import dask
    import h5py

    path = str(path)
    if not Path(path).exists():
        raise FileFormatError(f"file not found: {path}")
    try:
        with h5py.File(path, "r") as fh:
            if dataset not in fh:
                names = [k for k in fh if isinstance(fh[k], h5py.Dataset)]
                raise InputError(f"no dataset '{dataset}' in {path}; datasets: {', '.join(names) or 'none'}")
            shape = fh[dataset].shape
            t = fh[time_dataset][()] if time_dataset else None
            if fs is None and t is None:
                fs_attr = fh[dataset].attrs.get("fs", fh.attrs.get("fs"))
                fs = float(fs_attr) if fs_attr is not None else None
    except OSError as exc:
        raise FileFormatError(f"{path} is not a readable HDF5 file: {exc}") from None
    if len(shape) != 2:
        raise InputError(f"dataset '{dataset}' has shape {shape}; expected (n_channels, n_samples)")
    if fs is None and t is None:
        raise InputError(f"no sample rate for '{dataset}': give --fs or a time dataset")
    tasks = [dask.delayed(_fit_hdf5_rows)(path, dataset, c0, min(c0 + chunk_channels, shape[0]), t, fs, freq, harmonics)
             for c0 in range(0, shape[0], chunk_channels)]
    try:
        from dask.distributed import as_completed, get_client

        client = get_client()
    except (ImportError, ValueError):
        client = None
    if client is not None:
        futures = client.compute(tasks)
        index = {f.key: i for i, f in enumerate(futures)}
        parts: list[Any] = [None] * len(tasks)
        for fut in as_completed(futures):
            parts[index[fut.key]] = fut.result()
            if progress:
                progress(parts[index[fut.key]].shape[0])
    else:
        parts = list(dask.compute(*tasks))
        if progress:
            progress(shape[0])
    return _to_result(np.concatenate(parts, axis=0), int(shape[1]))
