"""Stage 1 for keyframe-only eyes: the offset from rotation angles over keyframe pairs (screw
congruence, eq. 9), and the pipeline around it.

Tolerances: the simulated eye's error is a random walk per 20 Hz frame, so a keyframe pair 0.3-3
s apart carries the error of 6-60 frames: at level 5 about 0.7 deg on its angle, which at the
protocol's ~0.5 rad/s change of angle per second of lag puts single pairs ~25 ms off and 60 s of
keyframes (~60 pairs) a few ms off. Noise-free, the search is exact to the refinement's
tolerance (1 us); with noise the tests allow 4 reported sigmas after the batch stage.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import recording

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import TimeAlignmentError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import calibration_error, keyframes_only, with_dropouts
from handeye_ros.core.time.keyframe_only import align_time_keyframes
from handeye_ros.core.trajectory import is_keyframe_only


def test_detected_from_the_stamps() -> None:
    """A 20 Hz eye is dense; its keyframes at 0.3-3 Hz are not, and neither is a 20 Hz eye
    with holes over most of its span (DSO's layout)."""
    rec = recording(seed=1)
    kf = keyframes_only(rec.eye, np.random.default_rng(1))
    assert not is_keyframe_only(rec.eye) and not is_keyframe_only(rec.hand)
    assert is_keyframe_only(kf)
    t = rec.eye.seconds(int(rec.eye.t_ns[0]))
    holey = rec.eye.select((t % 2.0) < 0.6)  # 0.6 s of every 2 s
    assert is_keyframe_only(holey)


@pytest.mark.parametrize('dt', [-0.35, 0.0, 0.0421])
def test_noise_free_is_exact(dt: float) -> None:
    from handeye_ros.core.simulate import Truth, random_truth

    t = random_truth(np.random.default_rng(2))
    rec = recording(seed=2, truth=Truth(dt, t.q_HE, t.p_HE, t.q_WG, t.p_WG))
    kf = keyframes_only(rec.eye, np.random.default_rng(2))
    ta = align_time_keyframes(rec.hand, kf)
    assert ta.method == 'keyframes'
    assert ta.time_offset_s == pytest.approx(dt, abs=2e-5)
    assert ta.peak_correlation > 0.999 and ta.second_peak_ratio < 0.9


def test_window_and_clocks_far_apart() -> None:
    """The eye's clock 1000 s ahead: found over every lag, and within a window around it."""
    rec = recording(seed=3, level=2.0)
    kf = keyframes_only(rec.eye, np.random.default_rng(3)).shifted(1_000_000_000_000)
    truth = rec.truth.time_offset_s + 1000.0
    for kwargs in ({}, {'time_offset_guess': 1000.0, 'max_time_offset': 0.5}):
        ta = align_time_keyframes(rec.hand, kf, **kwargs)
        assert ta.time_offset_s == pytest.approx(truth, abs=0.01)
    with pytest.raises(TimeAlignmentError, match='do not agree in the search window.*widen'):
        align_time_keyframes(rec.hand, kf, time_offset_guess=999.0, max_time_offset=0.5)


def test_pipeline_on_keyframes_with_mocap_dropouts() -> None:
    """Keyframes of a 3-minute recording whose MoCap lost 15 % in 0.2-1 s dropouts: the
    keyframe search runs (and says so), the batch stage gives an uncertainty that holds the
    truth within 4 sigma, and keyframe pairs that span a dropout are used."""
    rec = recording(seed=4, level=3.0, duration_s=180.0)
    rng = np.random.default_rng(4)
    hand = with_dropouts(rec.hand, rng, 0.15, (0.2, 1.0))
    kf = keyframes_only(rec.eye, rng)
    res = calibrate(hand, kf)
    assert res.time_alignment.method == 'keyframes'
    assert any('keyframes only' in w for w in res.warnings)
    b = res.batch
    assert b is not None
    err = calibration_error(rec.truth, res.time_offset_s, res.q_HE, res.p_HE)
    assert err.time_offset_s < max(4 * b.std[0], 1e-3)
    assert err.translation_m < 4 * np.linalg.norm(b.std[1:4])
    assert err.rotation_deg < 4 * np.degrees(np.linalg.norm(b.std[4:7]))
    # a pair spans a dropout when a hand gap lies between its two stamps; some are used
    th = hand.t_ns
    gap = np.flatnonzero(np.diff(th) > 100_000_000)
    te = kf.t_ns - res.time_offset_ns
    spans = sum(int(np.sum((te[:-1] < th[g]) & (te[1:] > th[g + 1]))) for g in gap)
    assert spans > 0 and b.n_eye_residuals > len(kf) - 1 - spans


def test_bad_keyframe_input_is_named() -> None:
    """Too few keyframes, and keyframes of an eye that does not rotate, end in one clear
    message each (no traceback, no number)."""
    rec = recording(seed=5, level=2.0)
    few = keyframes_only(rec.eye, np.random.default_rng(5)).select(np.arange(8))
    with pytest.raises(TimeAlignmentError, match='keyframe pairs; the time offset'):
        align_time_keyframes(rec.hand, few)
    still = recording(seed=5, motion='one_axis')
    kf = keyframes_only(still.eye, np.random.default_rng(5))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (len(kf), 1))
    from handeye_ros.core.trajectory import Trajectory

    frozen = Trajectory.from_arrays(kf.t_ns, kf.p_xyz, q, 'still eye')
    with pytest.raises(TimeAlignmentError, match='hardly rotate'):
        align_time_keyframes(still.hand, frozen)
    with pytest.raises(Exception, match='keyframe') as info:
        calibrate(rec.hand, few, CalibrationConfig())
    assert 'Traceback' not in str(info.value)
