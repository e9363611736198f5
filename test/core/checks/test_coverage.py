"""The MoCap's coverage of the eye's span (gaps inside it, the part covered), as the result
reports it. The simulated eye spans the hand less 1 s at each end (58 s of a 60 s hand)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import recording

from handeye_ros.core.checks.coverage import mocap_coverage
from handeye_ros.core.checks.verdict import Verdict
from handeye_ros.core.simulate import Truth, calibration_error, two_windows
from handeye_ros.core.trajectory import Trajectory


def test_whole_windows_and_a_dropout() -> None:
    rec = recording(seed=1)
    dt = rec.truth.time_offset_s
    whole = mocap_coverage(rec.hand, rec.eye, dt)
    assert whole.gaps == 0 and whole.fraction == pytest.approx(1.0, abs=1e-6)
    assert whole.note() == ''
    # 15 s at each end of the hand's 60 s: the eye's 58 s hold 2 x (15 - ~1) s of it
    ends = mocap_coverage(two_windows(rec.hand, 15.0), rec.eye, dt)
    assert ends.gaps == 1 and ends.longest_gap_s == pytest.approx(30.0, abs=0.05)
    lead = (rec.eye.t_ns[0] - rec.hand.t_ns[0]) * 1e-9 - dt
    tail = (rec.hand.t_ns[-1] - rec.eye.t_ns[-1]) * 1e-9 + dt
    assert ends.covered_s == pytest.approx(30.0 - lead - tail, abs=0.05)
    assert 'covers 48%' in ends.note() or 'covers 47%' in ends.note()
    t = rec.hand.seconds(int(rec.hand.t_ns[0]))
    hole = mocap_coverage(rec.hand.select(~((t > 20.0) & (t < 22.0))), rec.eye, dt)
    assert hole.gaps == 1 and hole.gap_s == pytest.approx(2.0, abs=0.02)
    assert hole.covered_s == pytest.approx(whole.covered_s - 2.0, abs=0.02)


def test_in_the_result() -> None:
    rec = recording(seed=2, level=2.0)
    t = rec.hand.seconds(int(rec.hand.t_ns[0]))
    from handeye_ros.core.pipeline import calibrate

    d = calibrate(rec.hand.select(~((t > 30.0) & (t < 31.0))), rec.eye).to_dict()
    assert d['coverage']['hand_gaps'] == 1
    assert d['coverage']['hand_gap_s'] == pytest.approx(1.0, abs=0.02)
    assert any('the MoCap covers 98%' in n for n in d['quality']['notes'])
    assert np.isfinite(d['std']['time_offset'])


def test_in_the_reports(tmp_path) -> None:
    """The terminal report and the HTML report say the coverage, with the gaps."""
    from handeye_ros.core.pipeline import calibrate
    from handeye_ros.evaluation.html import _numbers
    from handeye_ros.evaluation.terminal import format_report

    rec = recording(seed=3, level=2.0)
    t = rec.hand.seconds(int(rec.hand.t_ns[0]))
    d = calibrate(rec.hand.select(~((t > 25.0) & (t < 27.0))), rec.eye).to_dict()
    text = format_report(d)
    assert "MoCap coverage: 97% of the eye's" in text and '1 gap(s) inside it (2.0 s' in text
    assert '1 gap(s), 2.0 s (longest 2.0' in _numbers(d)


def _two_takes(pause_s: float) -> tuple[Trajectory, Trajectory, Truth]:
    """Two 60-s takes of one rig (one truth, other motions) in one file each, both streams
    paused ``pause_s`` between them."""
    a = recording(seed=7, level=5.0)
    b = recording(seed=107, level=5.0, truth=a.truth)
    shift = int(a.hand.t_ns[-1] - b.hand.t_ns[0] + pause_s * 1e9)

    def joined(x: Trajectory, y: Trajectory) -> Trajectory:
        return Trajectory(
            np.r_[x.t_ns, y.t_ns + shift], np.r_[x.p_xyz, y.p_xyz], np.r_[x.q_xyzw, y.q_xyzw]
        )

    return joined(a.hand, b.hand), joined(a.eye, b.eye), a.truth


def test_two_takes_an_hour_apart_are_covered_and_calibrated() -> None:
    """A recording paused in both streams is neither a keyframe-only eye (its parts are long,
    however little of its span they fill) nor a MoCap that misses the eye: it calibrates as its
    takes do."""
    from handeye_ros.core.pipeline import calibrate
    from handeye_ros.core.trajectory import is_keyframe_only

    hand, eye, truth = _two_takes(3600.0)
    assert not is_keyframe_only(eye)
    cov = mocap_coverage(hand, eye, truth.time_offset_s)
    assert cov.gaps == 0 and cov.fraction == pytest.approx(1.0, abs=1e-3) and cov.note() == ''
    assert cov.eye_s == pytest.approx(116.0, abs=0.1)
    res = calibrate(hand, eye)
    err = calibration_error(truth, res.time_offset_s, res.q_HE, res.p_HE)
    assert res.quality.verdict is Verdict.GOOD
    # level 5 (0.5 mm / 0.02 deg per pose and level) over 2 x 58 s: within a few sigmas
    assert abs(err.time_offset_s) < 2e-3 and err.translation_m < 0.01 and err.rotation_deg < 0.5
