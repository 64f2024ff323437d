"""Sine fits of arrays too large for memory (HDF5 or Zarr), chunk by chunk on Dask.

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

__all__ = ["ArrayFit", "SUMMARY_FIELDS", "fit_sine_dask", "fit_stored_array", "fit_hdf5_dataset"]

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


def _is_zarr(path: str) -> bool:
    p = Path(path)
    return p.suffix.lower() == ".zarr" or (p.is_dir() and any((p / m).exists() for m in ("zarr.json", ".zgroup", ".zarray")))


def _read_rows(path: str, dataset: str, c0: int, c1: int) -> np.ndarray:
    if _is_zarr(path):
        import zarr

        return np.asarray(zarr.open_group(path, mode="r")[dataset][c0:c1])
    import h5py

    with h5py.File(path, "r") as fh:
        return fh[dataset][c0:c1]


def _fit_rows(path: str, dataset: str, c0: int, c1: int, t, fs, freq, harmonics) -> np.ndarray:
    return _summaries(_read_rows(path, dataset, c0, c1), t, fs, freq, harmonics)


def _store_info(path: str, dataset: str, time_dataset: str | None):
    """(shape, fs attribute or None, time stamps or None) of a 2-D dataset in HDF5 or Zarr."""
    if _is_zarr(path):
        import zarr

        try:
            grp = zarr.open_group(path, mode="r")
        except Exception as exc:  # zarr raises several types for a non-store
            raise FileFormatError(f"{path} is not a readable Zarr store: {str(exc).splitlines()[0]}") from None
        names = [k for k, _ in grp.arrays()]
        if dataset not in names:
            raise InputError(f"no dataset '{dataset}' in {path}; datasets: {', '.join(names) or 'none'}")
        arr = grp[dataset]
        fs_attr = arr.attrs.get("fs", grp.attrs.get("fs"))
        t = np.asarray(grp[time_dataset][:]) if time_dataset else None
        return arr.shape, fs_attr, t
    import h5py

    try:
        with h5py.File(path, "r") as fh:
            if dataset not in fh:
                names = [k for k in fh if isinstance(fh[k], h5py.Dataset)]
                raise InputError(f"no dataset '{dataset}' in {path}; datasets: {', '.join(names) or 'none'}")
            fs_attr = fh[dataset].attrs.get("fs", fh.attrs.get("fs"))
            t = fh[time_dataset][()] if time_dataset else None
            return fh[dataset].shape, fs_attr, t
    except OSError as exc:
        raise FileFormatError(f"{path} is not a readable HDF5 file: {exc}") from None


def fit_stored_array(path: str | Path, dataset: str, *, fs: float | None = None, time_dataset: str | None = None,
                     freq: float | None = None, harmonics: int = 1, chunk_channels: int = 256,
                     progress: Any = None) -> ArrayFit:
    """Fit every row of a 2-D HDF5 or Zarr dataset (channels x samples) without loading it whole.

    Parameters
    ----------
    path : str or Path
        HDF5 file, or Zarr store (a ``.zarr`` folder).
    dataset : str
        Name of the 2-D array (channels x samples).
    fs : float, optional
        Sample rate in Hz (default: the dataset's or file's ``fs`` attribute).
    time_dataset : str, optional
        1-D array of time stamps in s instead of a sample rate.
    freq, harmonics
        As for :func:`senscal.fit_sine`.
    chunk_channels : int
        Channels per task.
    progress : callable, optional
        Called with the number of channels done as chunks complete.

    Notes
    -----
    Each task opens the store itself and reads only its rows, so this runs on
    a ``distributed`` cluster (the active client, if any) as well as on
    threads.
    """
    import dask

    path = str(path)
    if not Path(path).exists():
        raise FileFormatError(f"file not found: {path}")
    shape, fs_attr, t = _store_info(path, dataset, time_dataset)
    if fs is None and t is None and fs_attr is not None:
        fs = float(fs_attr)
    if len(shape) != 2:
        raise InputError(f"dataset '{dataset}' has shape {shape}; expected (n_channels, n_samples)")
    if fs is None and t is None:
        raise InputError(f"no sample rate for '{dataset}': give --fs or a time dataset")
    tasks = [dask.delayed(_fit_rows)(path, dataset, c0, min(c0 + chunk_channels, shape[0]), t, fs, freq, harmonics)
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


# The HDF5-only name of the first release.
fit_hdf5_dataset = fit_stored_array
