"""``senscal simulate sine``."""

from __future__ import annotations

import math

from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import units
from senscal.cli.app import simulate_app
from senscal.cli.common import console, err_console
from senscal.io import write_recording
from senscal.io.guard import is_stdio
from senscal.simulate import simulate_sine, write_truth


@simulate_app.command("sine")
@units(fs='Hz', duration='s', freq='Hz', t0='s', jitter='s')
def simulate_sine_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder; - writes the recording (CSV) to stdout.")],
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
    channels: Annotated[int, typer.Option("--channels", help="Number of channels.")] = 4,
    fs: Annotated[str, typer.Option("--fs", help="Sample rate in Hz.")] = "1000.0",
    duration: Annotated[str, typer.Option("--duration", help="Record length in s.")] = "2.0",
    freq: Annotated[str, typer.Option("--freq", help="Frequency in Hz.")] = "12.5",
    noise: Annotated[float, typer.Option("--noise", help="Noise standard deviation.")] = 0.05,
    t0: Annotated[str, typer.Option(
        "--t0", help="Time of the first sample in s (a record far from t = 0: phase at t = 0 vs at the centre).")] = "0.0",
    noise_rho: Annotated[float, typer.Option(
        "--noise-rho", help="Coloured noise: lag-one correlation of AR(1) noise, -1 < rho < 1 (0 = white).")] = 0.0,
    full_scale: Annotated[Optional[float], typer.Option(
        "--full-scale", help="ADC input range +/-FS (channel unit): samples beyond it are clipped.")] = None,
    adc_bits: Annotated[Optional[int], typer.Option(
        "--adc-bits", help="ADC resolution in bits over +/- --full-scale: samples quantised to 2 FS / 2^bits.")] = None,
    jitter: Annotated[str, typer.Option(
        "--jitter", help="Sample-clock/aperture jitter, RMS in s (each sample taken at t + delta, stamped t).")] = "0.0",
    flicker: Annotated[float, typer.Option(
        "--flicker", help="1/f noise: amplitude spectral density at 1 Hz (channel unit/sqrt(Hz)).")] = 0.0,
) -> None:
    """A noisy multi-channel sine recording (sine.csv) and its truth (sine_truth.json)."""
    from senscal.errors import InputError

    if not (channels >= 1 and 0 < duration < math.inf and 0 < fs < math.inf and 0 <= noise < math.inf
            and 0 < freq < math.inf):
        raise InputError("channels >= 1, finite duration > 0, fs > 0, freq > 0 and noise >= 0 are required")
    if not math.isfinite(t0):
        raise InputError(f"--t0 must be a finite time in s, got {t0}")
    if not -1.0 < noise_rho < 1.0:
        raise InputError(f"--noise-rho must lie strictly between -1 and 1 (stationary AR(1) noise), got {noise_rho}")
    if full_scale is not None and not (0 < full_scale < math.inf):
        raise InputError(f"--full-scale must be a positive range in the channel's unit, got {full_scale}")
    if adc_bits is not None and (full_scale is None or not 1 <= adc_bits <= 32):
        raise InputError("--adc-bits needs --full-scale (the range it divides) and lies in 1..32")
    if not (0 <= jitter < math.inf and 0 <= flicker < math.inf):
        raise InputError("--jitter (s) and --flicker (unit/sqrt(Hz)) must be finite and >= 0")
    lsb = 2.0 * full_scale / 2**adc_bits if adc_bits is not None else None
    rec, truth = simulate_sine(n_channels=channels, fs=fs, duration=duration, frequency=freq, noise=noise,
                               t0=t0, noise_rho=noise_rho, clip=full_scale, lsb=lsb, jitter=jitter,
                               flicker=flicker, seed=seed)
    if is_stdio(out):
        # A pipe takes one file: the recording (senscal simulate sine --out - | senscal fit -).
        write_recording(rec, out)
        err_console.print("wrote sine.csv to standard output; the truth file needs --out FOLDER")
        return
    p = write_recording(rec, out / "sine.csv")
    q = write_truth(truth, out / "sine_truth.json")
    console.print(f"wrote {p} and {q}")
