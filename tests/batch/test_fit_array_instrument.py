"""fit-array reports what the converter did per channel, as `senscal fit` does (issue 25)."""

from __future__ import annotations

import math

import numpy as np

from senscal.batch.arrays import fit_sine_dask
from senscal.simulate.sine import adc


def test_fit_array_columns_flag_clipping_and_under_dithering():
    rng = np.random.default_rng(1)
    t = np.arange(2000) / 1000.0
    clean = np.sin(2 * math.pi * 12.5 * t) + 0.3
    y = np.stack([clean + rng.normal(0, 0.05, t.size),                              # white
                  adc(clean + rng.normal(0, 0.05, t.size), clip=(-5, 1.25)),        # clipped crest
                  adc(clean + rng.normal(0, 0.0015, t.size), lsb=4 / 256)])         # 0.1 LSB of noise
    res = fit_sine_dask(y, fs=1000.0, freq=12.5, chunk_channels=2)
    assert res.n_clipped[0] == 0 and res.n_clipped[1] > 100 and res.clip_handled[1] == 1
    # Handled: the clipped channel's amplitude is within its u of the truth.
    assert abs(res.amplitude[1] - 1.0) <= 3 * res.u_amplitude[1]
    assert np.isnan(res.lsb[0]) and res.lsb[2] == 4 / 256
    assert res.under_dithered.tolist() == [0.0, 0.0, 1.0]


def test_fit_array_command_counts_flagged_channels(cli, tmp_path):
    import h5py

    rng = np.random.default_rng(2)
    t = np.arange(2000) / 1000.0
    y = np.stack([adc(np.sin(2 * math.pi * 12.5 * t) + rng.normal(0, 0.0015, t.size), lsb=4 / 256)
                  for _ in range(3)])
    p = tmp_path / "a.h5"
    with h5py.File(p, "w") as fh:
        fh.create_dataset("y", data=y).attrs["fs"] = 1000.0
    r = cli("fit-array", p, "--dataset", "y", "--out", tmp_path / "o.csv", "--freq", "12.5", "--json")
    assert r.code == 0, r.err
    assert '"n_under_dithered": 3' in r.out and "under-dithered" in r.err
    head = (tmp_path / "o.csv").read_text().splitlines()[0]
    assert "under_dithered" in head and "lsb" in head and "n_clipped" in head
