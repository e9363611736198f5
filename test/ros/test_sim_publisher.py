"""sim_publisher's recordings without DDS: a replay of two trajectory files is those files'
poses, with no truth, and its --bag holds them as a simulated recording's does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip('rclpy')

from handeye_ros.app.replay import replay
from handeye_ros.core.simulate import simulate
from handeye_ros.formats import write_euroc, write_tum
from handeye_ros.ros.sim_options import parse
from handeye_ros.ros.sim_publisher import _recording, _speed
from handeye_ros.stream import StreamConfig


def test_a_replay_is_the_files_poses_paced_by_their_stamps(tmp_path: Path) -> None:
    rec = simulate(5, duration_s=12.0)
    hand, eye = tmp_path / 'hand.csv', tmp_path / 'eye.txt'
    write_euroc(hand, rec.hand)  # EuRoC: w x y z on disk
    write_tum(eye, rec.eye)
    bag = tmp_path / 'replay'
    args = parse(['--replay', str(hand), str(eye), '--bag', f'{bag}:mcap'])
    out = _recording(args)
    assert out.truth is None and _speed(args) == 1.0
    for got, want in ((out.hand, rec.hand), (out.eye, rec.eye)):
        np.testing.assert_array_equal(got.t_ns, want.t_ns)
        np.testing.assert_allclose(got.p_xyz, want.p_xyz, atol=1e-9)
        np.testing.assert_allclose(np.abs(np.sum(got.q_xyzw * want.q_xyzw, 1)), 1.0, atol=1e-12)
    written = replay(bag, StreamConfig(), progress=False).snapshot()
    np.testing.assert_array_equal(written.hand.t_ns, rec.hand.t_ns)
    np.testing.assert_array_equal(written.eye.t_ns, rec.eye.t_ns)
    # a simulation keeps --rate unless --speed asks for its stamps' pace
    assert _speed(parse([])) is None and _speed(parse(['--speed', '3'])) == 3.0


def test_a_replay_says_what_the_reader_noted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rec = simulate(5, duration_s=12.0)
    hand, eye = tmp_path / 'hand.csv', tmp_path / 'eye.txt'
    write_euroc(hand, rec.hand)
    write_tum(eye, rec.eye)
    lines = eye.read_text().splitlines()
    eye.write_text('\n'.join([*lines[:5], lines[4], *lines[5:]]) + '\n')  # one stamp twice
    out = _recording(parse(['--replay', str(hand), str(eye)]))
    assert len(out.eye) == len(rec.eye)
    assert 'stamp(s) written twice; the last row of each was kept' in capsys.readouterr().err
