"""Real recordings (tests/data, credits beside each file): the automatic model choice holds out (corrected
field norm of unseen time blocks) within 5 % of the best of full, diagonal, offsets and a plain ellipsoid fit, the hand-held one-axis turn is recognised as a turn
with its heading error, and quantised readings get a noise floor of at least step / sqrt(12)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from senscal.triaxial import calibrate
from senscal.triaxial.estimators import fit_algebraic
from senscal.triaxial.selection import held_out_norm_error, held_out_residuals

DATA = Path(__file__).resolve().parents[1] / "data"


def _sphere():
    return pd.read_csv(DATA / "mag_sunsided_full_sphere_hmc5883l_dec4.csv")[["x", "y", "z"]].to_numpy().T


def _turn():
    return pd.read_csv(DATA / "mag_sunsided_level_turn_hmc5883l.csv")[["x", "y", "z"]].to_numpy().T


def _qmc():
    # Two metadata lines (Fs, initialisation time) before the header; 10 Hz after decimation, so the
    # first 60 s of static readings are the first 600 rows.
    d = pd.read_csv(DATA / "mag_tomisuarez2_qmc5883l_dec5.csv", skiprows=2)
    return d[["mx", "my", "mz"]].to_numpy(float).T[:, 600:]


def _ck(kind):
    d = pd.read_csv(DATA / "magacc_ckexplorer_tumble_dec6.csv")
    return d[[f"{kind}x", f"{kind}y", f"{kind}z"]].to_numpy().T


RECORDINGS = {"hmc5883l-sphere": _sphere, "hmc5883l-turn": _turn, "qmc5883l": _qmc,
              "ckexplorer-mag": lambda: _ck("m"), "ckexplorer-acc": lambda: _ck("a")}


def _ellipsoid_held_out(h):
    """A plain algebraic ellipsoid fit, scored like the candidates: held-out corrected 3-D norm error, %."""
    r, _ = held_out_residuals(h, lambda hh: fit_algebraic(hh, "full"),
                              lambda f, ht: held_out_norm_error(f.calibration, ht))
    return 100 * float(np.sqrt(np.mean(r ** 2)))


@pytest.mark.parametrize("name", sorted(RECORDINGS))
def test_automatic_choice_holds_out_within_5_percent_of_the_best(name):
    # The criterion of issue 26: the corrected field norm of held-out blocks (what `apply` gives on new
    # data) of the automatic choice is within 5 % of the best of full, diagonal and offsets.
    h = RECORDINGS[name]()
    res = calibrate(h)
    ev = {e["model"]: e for e in res.model_evidence}
    chosen = ev[res.model]["held_out_percent"]
    best = min(ev[m]["held_out_percent"] for m in ("full", "diagonal", "offsets")
               if ev[m]["held_out_percent"] is not None)
    assert chosen <= 1.05 * best, (res.model, chosen, best)
    if not res.planarity["thickness"] < res.planarity["thickness_threshold"]:
        # Scored on the 3-D norm: a plain ellipsoid fit (no outlier screening) is no better either.
        assert chosen <= 1.05 * _ellipsoid_held_out(h), (res.model, chosen)
    # Every null parameter is explained.
    nulls = {n for n, p in res.parameters.items() if p["value"] is None}
    explained = {p for g in res.unidentifiable for p in g["parameters"]}
    assert nulls <= explained


def test_hand_held_turn_is_a_one_axis_turn_with_heading_error():
    h = _turn()
    res = calibrate(h)
    assert res.planarity["planar"]
    assert res.planarity["evidence"]["confounded_by_one_axis_turn"]
    hd = res.heading
    assert hd is not None and hd["U_after_deg"]["k"] == 2
    # Hard iron here is comparable to the horizontal field: the raw heading is tens of degrees off, and the
    # calibrated one is known to a few degrees.
    assert hd["deviation_before_deg"]["rms"] > 10 * hd["U_after_deg"]["rms"]
    # The parameters the turn cannot determine are null, not numbers with huge U.
    nulls = [n for n, p in res.parameters.items() if p["value"] is None]
    assert nulls and all(res.parameters[n]["u"] is None for n in nulls)


def test_quantised_readings_floor_is_step_over_sqrt12():
    h = _turn()
    res = calibrate(h)
    step = 1 / 1090  # HMC5883L at gain 1.3 Ga: 1090 LSB/gauss
    assert res.conditioning["quantisation_step"] == pytest.approx(step, rel=1e-3)
    assert res.conditioning["noise_floor"] >= step / math.sqrt(12) * (1 - 1e-6)  # file keeps 9 digits
