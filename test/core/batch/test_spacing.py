"""The hand spline's spacing where the MoCap is noisy for its eye (core/batch/spacing.py): a
wider spacing where the eye's relative motions say it predicts them better, none where they do
not."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import recording
from scipy.spatial.transform import Rotation

from handeye_ros.core.config import KNOT_SPACING_S
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.result import CalibrationResult
from handeye_ros.core.simulate import Truth, with_dropouts


def _within_3_sigma(res: CalibrationResult, truth: Truth) -> bool:
    """dt, T_HE's translation and rotation (per axis) within 3 of their reported sigmas."""
    b = res.batch
    assert b is not None
    turn = Rotation.from_quat(b.q_HE).inv() * Rotation.from_quat(truth.q_HE)
    err = np.concatenate(
        ([res.time_offset_s - truth.time_offset_s], b.p_HE - truth.p_HE, turn.as_rotvec())
    )
    return bool(np.all(np.abs(err) < 3 * b.std[:7]))


def test_a_jittery_mocap_gets_the_wider_spacing_its_eye_supports() -> None:
    """A 100 Hz MoCap with 0.5 deg and 2 mm of jitter a pose, against a VIO at noise level 5:
    held through knots every 0.0527 s, its rotation noise drew the lever arm 8.8 % short and dt
    1 ms off (20 seeds: the truth inside 3 sigmas for every component in 55 %). The eye's
    residuals pick a spacing four times wider; the truth is then inside 3 sigmas, and the
    noise drawn once more moves the answer by under a sigma, which a note says."""
    rec = recording(seed=0, level=5.0, hand_noise_deg=0.5, hand_noise_m=2e-3)
    res = calibrate(rec.hand, rec.eye)
    assert res.batch is not None and res.batch.knot_spacing > 3 * KNOT_SPACING_S
    assert _within_3_sigma(res, rec.truth)
    assert res.batch.mocap_noise_move is not None and res.batch.mocap_noise_move < 1.0
    assert res.quality.verdict == 'good'
    assert any('its spline is knotted every 0.211 s' in n for n in res.quality.notes)


def test_a_slow_mocap_spline_through_its_samples_only_when_they_are_exact() -> None:
    """A 30 Hz MoCap (a camera tracking a tag) gets a spline through its samples: no residual
    is left to measure its noise by. With 0.5 deg and 2 mm of jitter that spline carried the
    jitter whole: 40-64 mm of lever arm lost and 4.5 ms of offset, called `good` (6 seeds). The
    eye's residuals now pick a spacing the samples are fitted at; without jitter they keep the
    spline through the samples, and the answer is the same as before."""
    rec = recording(seed=1, level=5.0, hand_rate_hz=30.0, hand_noise_deg=0.5, hand_noise_m=2e-3)
    res = calibrate(rec.hand, rec.eye)
    assert res.batch is not None and res.batch.knot_spacing > 2 / 30.0
    assert _within_3_sigma(res, rec.truth)
    exact = recording(seed=1, level=5.0, hand_rate_hz=30.0)
    res = calibrate(exact.hand, exact.eye)
    assert res.batch is not None and res.batch.knot_spacing == pytest.approx(1 / 30.0, rel=1e-6)
    assert res.batch.mocap_noise_move is None
    assert _within_3_sigma(res, exact.truth)


def test_an_exact_mocap_keeps_the_default_spacing() -> None:
    """The paper's protocol (a noise-free MoCap at 100 Hz): the spline's error is under 1 % of
    the eye's, nothing is tried and nothing measured."""
    rec = recording(seed=0, level=5.0)
    res = calibrate(rec.hand, rec.eye)
    assert res.batch is not None and res.batch.knot_spacing == KNOT_SPACING_S
    assert res.batch.mocap_noise_move is None


def test_a_jittery_mocap_with_dropouts_is_spaced_by_its_pieces() -> None:
    """The same jitter with 15 % of the MoCap lost in dropouts of 0.2-5 s: each gap-free part
    gets its own spline at the wider spacing, the eye's pairs are compared where both splines
    reach (blocks without a pair left out), and the truth stays inside 3 sigmas."""
    rec = recording(seed=0, level=5.0, hand_noise_deg=0.5, hand_noise_m=2e-3)
    hand = with_dropouts(rec.hand, np.random.default_rng(0), 0.15)
    res = calibrate(hand, rec.eye)
    assert res.batch is not None and res.batch.knot_spacing > 3 * KNOT_SPACING_S
    assert any('(knots every 0.2108 s)' in w and 'gap-free parts' in w for w in res.warnings)
    assert _within_3_sigma(res, rec.truth)
