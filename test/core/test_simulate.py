"""The simulator's own limits: a recording too short to hold eye poses is refused."""

from __future__ import annotations

import math

import pytest

from handeye_ros.core.errors import InputError
from handeye_ros.core.simulate import simulate


@pytest.mark.parametrize('duration_s', [0.5, 2.0, math.nan])
def test_a_recording_without_eye_poses_is_refused(duration_s: float) -> None:
    """The eye covers the span less 1 s at each end: 2 s and less hold none."""
    with pytest.raises(InputError, match='holds no eye poses'):
        simulate(0, duration_s=duration_s)


def test_the_shortest_recording_holds_three_eye_poses() -> None:
    rec = simulate(0, duration_s=2.1, eye_rate_hz=20.0)
    assert len(rec.eye) == 3 and len(rec.hand) == 211
