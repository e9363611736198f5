"""auto_calibrate's rule for a later result (status.judge): published only when it improves,
converged once it improves too little; and how the status tells that a clock jumped."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip('diagnostic_msgs')

from handeye_ros.ros.status import GROWTH, IMPROVEMENT, clocks_apart, judge


@pytest.mark.parametrize(
    ('sigmas', 'published', 'auto', 'targets', 'expected'),
    [
        # the first result, or one asked for by ~/calibrate: published, nothing judged
        ((1.0, 1.0, 1.0), None, True, (1.0, 1.0, 1.0), (True, False)),
        ((9.0, 9.0, 9.0), (1.0, 1.0, 1.0), False, (1.0, 1.0, 1.0), (True, False)),
        # auto: every sigma smaller by more than IMPROVEMENT: published, keeps going
        ((0.8, 0.8, 0.8), (1.0, 1.0, 1.0), True, (1.0, 1.0, 1.0), (True, False)),
        # one sigma still improves by more than IMPROVEMENT: keeps going
        ((0.95, 0.8, 0.99), (1.0, 1.0, 1.0), True, (1.0, 1.0, 1.0), (True, False)),
        # every sigma smaller, none by IMPROVEMENT: published, converged
        ((0.95, 0.95, 0.99), (1.0, 1.0, 1.0), True, (1.0, 1.0, 1.0), (True, True)),
        # one sigma larger: the published result stays, converged
        ((0.5, 0.5, 1.01), (1.0, 1.0, 1.0), True, (1.0, 1.0, 1.0), (False, True)),
        # far below the targets, 18 % less is under 10 % of the target: converged
        ((0.41, 0.41, 0.41), (0.5, 0.5, 0.5), True, (1.0, 1.0, 1.0), (True, True)),
        # above a target (the translation's), 18 % of itself counts: keeps going
        ((0.41, 0.82, 0.41), (0.5, 1.0, 0.5), True, (1.0, 0.5, 1.0), (True, False)),
    ],
)
def test_a_later_auto_result(sigmas, published, auto, targets, expected) -> None:
    assert IMPROVEMENT == 0.1
    assert judge(sigmas, published, auto, targets) == expected


def test_white_noise_converges_once_the_sigmas_are_about_half_the_targets() -> None:
    """White noise shrinks every sigma by 1/sqrt(GROWTH) at each later result, for ever: auto
    mode stops once more recording no longer matters to the verdict."""
    targets, sigma = (1e-3, 0.01, 0.0087), np.array([1e-3, 0.01, 0.0087])  # READY: at them
    for results in range(2, 20):
        new = sigma / np.sqrt(GROWTH)
        admitted, converged = judge(tuple(new), tuple(sigma), True, targets)
        assert admitted
        sigma = new
        if converged:
            break
    assert converged and results <= 6, results
    assert np.all(sigma / targets < 0.6) and np.all(sigma / targets > 0.3), sigma / targets


def test_the_clocks_move_apart_only_when_stamps_move_unlike_arrivals() -> None:
    """A 100 Hz MoCap and a 20 Hz device published in real time (arrival = stamp + 5 ms)."""
    hand = np.arange(0, 2000) * 10_000_000  # ns, 20 s
    eye = np.arange(0, 400) * 50_000_000

    def apart(h_end: float, e_end: float, e_seen: float, jump_s: float = 0.0) -> float:
        h, e = hand[hand <= h_end * 1e9], eye[eye <= e_end * 1e9]
        e_stamp = e.copy()
        e_stamp[-1] += round(jump_s * 1e9)
        seen = {'hand': h[-1] * 1e-9 + 0.005, 'eye': e_seen}
        return clocks_apart(h, e_stamp, seen)

    first = apart(10.0, 10.0, 10.005)
    # the device's stream ends 1 s before the MoCap's: nothing moved
    assert apart(19.0, 18.0, 18.005) == pytest.approx(first, abs=1e-9)
    # its messages keep coming but are refused for 3 s (a clock that went back 3 s)
    assert apart(19.0, 16.0, 19.005) - first == pytest.approx(-3.0, abs=1e-9)
    # its clock jumped 5 s forward
    assert apart(19.0, 19.0, 19.005, jump_s=5.0) - first == pytest.approx(5.0, abs=1e-9)
