"""auto_calibrate's rule for a later result (status.judge): published only when it improves,
converged once it improves too little."""

from __future__ import annotations

import pytest

pytest.importorskip('diagnostic_msgs')

from handeye_ros.ros.status import IMPROVEMENT, judge


@pytest.mark.parametrize(
    ('sigmas', 'published', 'auto', 'expected'),
    [
        # the first result, or one asked for by ~/calibrate: published, nothing judged
        ((1.0, 1.0, 1.0), None, True, (True, False)),
        ((9.0, 9.0, 9.0), (1.0, 1.0, 1.0), False, (True, False)),
        # auto: every sigma smaller by more than IMPROVEMENT: published, keeps going
        ((0.8, 0.8, 0.8), (1.0, 1.0, 1.0), True, (True, False)),
        # one sigma still improves by more than IMPROVEMENT: keeps going
        ((0.95, 0.8, 0.99), (1.0, 1.0, 1.0), True, (True, False)),
        # every sigma smaller, none by IMPROVEMENT: published, converged
        ((0.95, 0.95, 0.99), (1.0, 1.0, 1.0), True, (True, True)),
        # one sigma larger: the published result stays, converged
        ((0.5, 0.5, 1.01), (1.0, 1.0, 1.0), True, (False, True)),
    ],
)
def test_a_later_auto_result(sigmas, published, auto, expected) -> None:
    assert IMPROVEMENT == 0.1
    assert judge(sigmas, published, auto) == expected
