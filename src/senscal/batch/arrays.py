"""Sine fits of arrays too large for memory (HDF5 or Zarr), chunk by chunk on Dask.

The time axis of every chunk is whole (a fit needs the full record); the
channel axis is split, so 10,000 channels stream through the workers a chunk
at a time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import FileFormatError, InputError, SenscalError
from senscal.io.recording import check_time

__all__ = ["ArrayFit", "SUMMARY_FIELDS", "check_stored_array", "fit_sine_dask", "fit_stored_array", "fit_hdf5_dataset"]

FIT_FIELDS = ("frequency", "amplitude", "phase", "offset", "u_frequency", "u_amplitude", "u_phase",
              "u_offset", "residual_rms", "snr_db")
# What the converter did (senscal.io.instrument, as `senscal fit` reports it): samples at a clipped end,
# 1 where the clipping was handled (the fit used only samples away from the clip level), the ADC's LSB
# (NaN: no grid), 1 where the quantiser was under-dithered (u does not cover).
INSTRUMENT_FIELDS = ("n_clipped", "clip_handled", "lsb", "under_dithered")
SUMMARY_FIELDS = FIT_FIELDS + INSTRUMENT_FIELDS


@dataclass(frozen=True)
class ArrayFit(ResultMixin):
    """Per-channel sine-fit summaries of a large array (SI units, phase in rad).

    Every attribute of :data:`SUMMARY_FIELDS` is an array of shape (n_channels,):
    the fit's numbers and what the converter did (``n_clipped``,
    ``clip_handled``, ``lsb``, ``under_dithered``; see
    :func:`senscal.jobs.fit.instrument_check`).
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
    n_clipped: np.ndarray
    clip_handled: np.ndarray
    lsb: np.ndarray
    under_dithered: np.ndarray
    n_samples: int

    @property
    def n_channels(self) -> int:
        return int(self.amplitude.shape[0])


def _summaries(block: np.ndarray, t, fs, freq, harmonics) -> np.ndarray:
    from senscal.jobs.fit import instrument_check
    from senscal.sinefit import fit_sine

    block = np.asarray(block, dtype=np.float64)
    tt = np.asarray(t, dtype=float) if t is not None else np.arange(block.shape[-1]) / float(fs)
    if freq is not None:
        batch = fit_sine(block, t, fs=fs, freq=freq, harmonics=harmonics)
        fits = [batch.channel(i) for i in range(block.shape[0])] if batch.shape else [batch]
    else:
        fits = [fit_sine(block[i], t, fs=fs, harmonics=harmonics) for i in range(block.shape[0])]
    rows = []
    for i, fit in enumerate(fits):
        fit, found, _, _ = instrument_check(block[i], tt, fit, freq=freq, harmonics=harmonics)
        rows.append([float(getattr(fit, f)) for f in FIT_FIELDS]
                    + [float(found.n_clipped), float(found.clipped and bool(found.handled)),
                       float(found.lsb) if found.lsb is not None else math.nan, float(bool(found.under_dithered))])
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
    """(shape, fs attribute or None, time stamps or None) of a 2-D dataset in HDF5 or Zarr.

    Any failure to open or parse the store (corrupt file, a group where a
    dataset is expected, strings, empty or damaged datasets) is one
    :class:`FileFormatError` naming the file.
    """
    if time_dataset is not None and not str(time_dataset).strip():
        raise InputError("--time-dataset is empty; give the name of the 1-D time dataset or leave it out")
    kind = "Zarr store" if _is_zarr(path) else "HDF5 file"
    try:
        shape, dtype, fs_attr, t = (_zarr_info if _is_zarr(path) else _hdf5_info)(path, dataset, time_dataset)
    except SenscalError:
        raise
    except MemoryError:
        raise FileFormatError(f"the time dataset of {path} does not fit in memory") from None
    except Exception as exc:
        # h5py/zarr raise OSError, KeyError, RuntimeError, TypeError ... on damaged stores.
        msg = " ".join(str(exc).split())[:200]
        raise FileFormatError(f"{path} is not a readable {kind} ({type(exc).__name__}: {msg})") from None
    if len(shape) != 2:
        raise InputError(f"dataset '{dataset}' has shape {shape}; expected (n_channels, n_samples)")
    if 0 in shape:
        raise InputError(f"dataset '{dataset}' in {path} is empty (shape {shape})")
    if np.dtype(dtype).kind not in "fiu":
        raise FileFormatError(f"dataset '{dataset}' in {path} holds {np.dtype(dtype)} values, not real numbers")
    if fs_attr is not None:
        try:
            fs_attr = float(np.asarray(fs_attr).reshape(()))
        except (TypeError, ValueError):
            raise FileFormatError(f"the 'fs' attribute of '{dataset}' in {path} is not one number") from None
        if not (math.isfinite(fs_attr) and fs_attr > 0):
            raise FileFormatError(f"the 'fs' attribute of '{dataset}' in {path} is {fs_attr}; it must be a "
                                  "positive number of Hz")
    if t is not None:
        t = np.asarray(t)
        if t.ndim != 1 or t.dtype.kind not in "fiu":
            raise FileFormatError(f"time dataset '{time_dataset}' in {path} must be 1-D numbers, "
                                  f"got shape {t.shape} of {t.dtype}")
        t = t.astype(np.float64)
        if t.size != shape[1]:
            raise InputError(f"time dataset '{time_dataset}' has {t.size} samples but '{dataset}' has {shape[1]}")
        check_time(t, source=path, name=str(time_dataset))
    return shape, fs_attr, t


def _zarr_info(path: str, dataset: str, time_dataset: str | None):
    import zarr

    try:
        grp = zarr.open_group(path, mode="r")
    except Exception as exc:  # zarr raises several types for a non-store
        raise FileFormatError(f"{path} is not a readable Zarr store: {str(exc).splitlines()[0]}") from None
    names = [k for k, _ in grp.arrays()]
    for name, what in ((dataset, "dataset"), (time_dataset, "time dataset")):
        if name is not None and name not in names:
            raise InputError(f"no {what} '{name}' in {path}; datasets: {', '.join(names) or 'none'}")
    arr = grp[dataset]
    fs_attr = arr.attrs.get("fs", grp.attrs.get("fs"))
    t = np.asarray(grp[time_dataset][:]) if time_dataset else None
    return arr.shape, arr.dtype, fs_attr, t


def _hdf5_info(path: str, dataset: str, time_dataset: str | None):
    import h5py

    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise FileFormatError(f"{path} is not a readable HDF5 file ({' '.join(str(exc).split())[:200]})") from None
    with fh:
        for name, what in ((dataset, "dataset"), (time_dataset, "time dataset")):
            if name is None:
                continue
            if name not in fh:
                names = [k for k in fh if isinstance(fh.get(k), h5py.Dataset)]
                raise InputError(f"no {what} '{name}' in {path}; datasets: {', '.join(names) or 'none'}")
            if not isinstance(fh[name], h5py.Dataset):
                raise InputError(f"'{name}' in {path} is a group, not a dataset; give the {what}'s full path")
        ds = fh[dataset]
        fs_attr = ds.attrs.get("fs", fh.attrs.get("fs"))
        t = fh[time_dataset][()] if time_dataset else None
        return ds.shape, ds.dtype, fs_attr, t


def check_stored_array(path: str | Path, dataset: str, *, fs: float | None = None, time_dataset: str | None = None,
                       freq: float | None = None, harmonics: int = 1, chunk_channels: int = 256):
    """Check a stored array and the fit's options before any work starts (no cluster needed).

    The file must exist and open, ``dataset`` must be a 2-D numeric array,
    a sample rate must come from ``fs``, the ``fs`` attribute or
    ``time_dataset``, and ``freq`` (with its harmonics) must lie below the
    Nyquist frequency.

    Returns
    -------
    (shape, fs, t)
        Shape (n_channels, n_samples), sample rate in Hz (None with time
        stamps), time stamps in s (None with a sample rate).

    Raises
    ------
    InputError, FileFormatError
        One line naming the problem and the fix.
    """
    path = str(path)
    if not Path(path).exists():
        raise FileFormatError(f"file not found: {path}")
    if fs is not None and not (math.isfinite(fs) and fs > 0):
        raise InputError(f"--fs must be a positive, finite sample rate in Hz, got {fs!r}")
    if freq is not None and not (math.isfinite(freq) and freq > 0):
        raise InputError(f"--freq must be a positive, finite frequency in Hz, got {freq!r}")
    if isinstance(harmonics, bool) or int(harmonics) != harmonics or harmonics < 1:
        raise InputError(f"--harmonics must be a whole number >= 1, got {harmonics!r}")
    if isinstance(chunk_channels, bool) or int(chunk_channels) != chunk_channels or chunk_channels < 1:
        raise InputError(f"--chunk must be a whole number >= 1, got {chunk_channels!r}")
    shape, fs_attr, t = _store_info(path, dataset, time_dataset)
    if fs is None and t is None and fs_attr is not None:
        fs = fs_attr
    if fs is None and t is None:
        raise InputError(f"no sample rate for '{dataset}': give --fs or a time dataset")
    if freq is not None and (fs is not None or t.size > 1):
        # The mean rate of irregular stamps is what the fit's Nyquist check uses too.
        rate = fs if fs is not None else (t.size - 1) / (t[-1] - t[0])
        if harmonics * freq >= rate / 2:
            raise InputError(f"--freq {freq:g} Hz{f' x {harmonics} harmonics' if harmonics > 1 else ''} is at or "
                             f"above the Nyquist frequency {rate / 2:g} Hz of '{dataset}'; check --freq and --fs")
    return shape, fs, t


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
    shape, fs, t = check_stored_array(path, dataset, fs=fs, time_dataset=time_dataset, freq=freq,
                                      harmonics=harmonics, chunk_channels=chunk_channels)
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
        try:
            parts = list(dask.compute(*tasks))
        except SenscalError:
            raise
        except (OSError, KeyError, RuntimeError, TypeError, ValueError) as exc:
            # A chunk that is damaged on disk shows up only when its task reads it.
            raise FileFormatError(f"cannot read dataset '{dataset}' of {path} ({type(exc).__name__}: "
                                  f"{' '.join(str(exc).split())[:200]})") from None
        if progress:
            progress(shape[0])
    return _to_result(np.concatenate(parts, axis=0), int(shape[1]))


# The HDF5-only name of the first release.
fit_hdf5_dataset = fit_stored_array
