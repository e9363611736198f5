"""The simulator's own limits: a recording it cannot make (too short to hold eye poses, too
long for memory, a negative seed, rate or noise) is refused saying why."""

from __future__ import annotations

import math

import pytest

from handeye_ros.core.errors import InputError
from handeye_ros.core.simulate import noise_level, simulate


@pytest.mark.parametrize('duration_s', [0.5, 2.0, math.nan])
def test_a_recording_without_eye_poses_is_refused(duration_s: float) -> None:
    """The eye covers the span less 1 s at each end: 2 s and less hold none."""
    with pytest.raises(InputError, match='holds no eye poses'):
        simulate(0, duration_s=duration_s)


def test_the_shortest_recording_holds_three_eye_poses() -> None:
    rec = simulate(0, duration_s=2.1, eye_rate_hz=20.0)
    assert len(rec.eye) == 3 and len(rec.hand) == 211


@pytest.mark.parametrize(
    ('kwargs', 'said'),
    [
        ({'seed': -1}, 'the seed is an integer >= 0'),
        ({'hand_rate_hz': 0.0}, 'the pose rates are positive numbers of Hz'),
        ({'eye_rate_hz': math.inf}, 'the pose rates are positive numbers of Hz'),
        ({'noise_m': math.nan}, 'the noise amounts are numbers >= 0'),
        ({'hand_noise_deg': -0.1}, 'the noise amounts are numbers >= 0'),
        # 10 h at 100 + 20 Hz fit; a day would hold 1e7 poses, refused before any array exists
        ({'duration_s': 86_400.0}, 'more than the 4,320,000'),
    ],
)
def test_a_simulation_it_cannot_make_is_refused_saying_why(
    kwargs: dict[str, float], said: str
) -> None:
    seed = int(kwargs.pop('seed', 0))
    with pytest.raises(InputError, match=said):
        simulate(seed, **kwargs)


@pytest.mark.parametrize('level', [-1.0, 10.5, math.nan])
def test_a_noise_level_outside_the_papers_is_refused(level: float) -> None:
    with pytest.raises(InputError, match="the noise level is one of the paper's, 0-10"):
        noise_level(level)
