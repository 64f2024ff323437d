"""Instrument findings of the reading layer: clipping and quantisation (senscal.io.instrument)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from senscal.io.instrument import (BIAS_FRACTION, clip_guard_mask, clipping_test, inspect_channel,
                                   quantisation_effect)
from senscal.simulate.sine import adc

T = np.arange(2000) / 1000.0


def _sine(rng, noise=0.05):
    return 1.0 * np.sin(2 * math.pi * 12.5 * T + rng.uniform(-3, 3)) + 0.3 + rng.normal(0, noise, T.size)


def test_continuous_channel_has_no_grid_and_no_clipping():
    f = inspect_channel(_sine(np.random.default_rng(1)))
    assert f.lsb is None and f.levels == 2000
    assert f.clipped_high is False and f.clipped_low is False and not f.clipped
    assert f.to_dict()["clipped"] is False


def test_text_with_few_decimals_is_not_a_converter_grid():
    # Six decimals: every gap is a multiple of 1e-6, but the values do not repeat.
    f = inspect_channel(np.round(_sine(np.random.default_rng(2)), 6))
    assert f.lsb is None


def test_quantised_channel_gives_its_lsb():
    y = adc(_sine(np.random.default_rng(3)), lsb=4 / 256)
    f = inspect_channel(y)
    assert f.lsb == pytest.approx(4 / 256, rel=1e-9)
    # A quantised crest repeats its top code without clipping: not judged without a model.
    assert f.clipped_high is None
    # A scaled grid (codes x volts per code, written as text) is found too.
    g = inspect_channel(np.round(np.round(y * 64) * 0.000305175, 9))
    assert g.lsb == pytest.approx(0.000305175, rel=1e-6)


def test_clipped_continuous_channel_is_found_without_a_model():
    y = adc(_sine(np.random.default_rng(4)), clip=(-5, 1.2))
    f = inspect_channel(y)
    assert f.clipped_high and not f.clipped_low and f.n_clipped == f.n_at_high > 50


def test_clipping_test_against_the_model():
    rng = np.random.default_rng(5)
    ph = rng.uniform(-3, 3)
    model = np.sin(2 * math.pi * 12.5 * T + ph) + 0.3
    # Unclipped records: the model's expected count beyond the extremes is ~Exp(1); the test's
    # false-alarm rate is 1e-3 per end, so 200 records x 2 ends should give (almost) none.
    alarms = 0
    for _ in range(200):
        y = adc(model + rng.normal(0, 0.05, T.size), lsb=4 / 256)
        ct = clipping_test(y, model, 0.05, lsb=4 / 256)
        alarms += ct.clipped_low + ct.clipped_high
    assert alarms <= 3   # P(>= 4 | mean 0.4) = 0.8 %
    # Clipped one noise sigma above the crest: a handful of samples pile up, and it is found.
    y = adc(model + rng.normal(0, 0.05, T.size), clip=(-5, 1.35))
    ct = clipping_test(y, model, 0.05)
    assert ct.clipped_high and not ct.clipped_low and ct.expected_beyond_high > -math.log(ct.alpha)


def test_guard_mask_keeps_no_sample_near_the_clip_level():
    rng = np.random.default_rng(6)
    model = np.sin(2 * math.pi * 12.5 * T) + 0.3
    y = adc(model + rng.normal(0, 0.05, T.size), clip=(-5, 1.25))
    keep = clip_guard_mask(y, model, 0.05, low=None, high=1.25)
    assert np.all(model[keep] < 1.25 - 3.4 * 0.05) and np.all(y[keep] < 1.25)
    assert 0.5 * T.size < keep.sum() < T.size


@pytest.mark.parametrize("noise_lsb, under", [(0.1, True), (0.2, True), (0.3, True), (0.6, False), (1.0, False)])
def test_under_dithered_from_the_residual(noise_lsb, under):
    q = 4 / 256
    rms = math.sqrt((noise_lsb * q) ** 2 + q * q / 12)
    u = rms / math.sqrt(2000)
    qe = quantisation_effect(q, rms, u)
    assert qe.noise_lsb == pytest.approx(noise_lsb, rel=1e-9)
    assert qe.under_dithered is under
    assert (qe.bias_bound > BIAS_FRACTION * u) is under
    if under:
        assert qe.warning().startswith("under-dithered: ")
