"""What ~/save may write, and where: only inside output_dir, never over a file that is not a
result, never changing an existing folder's mode; each refusal in one line, nothing changed on
disk."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

pytest.importorskip('rclpy')

from rclpy.parameter import Parameter

from handeye_ros.app.params_file import NodeConfig
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.formats.result_file import read_result
from handeye_ros.ros.files import REPORT_MARK
from handeye_ros.ros.jobs import Calibrated
from handeye_ros.ros.outputs import save
from handeye_ros.ros.parameters import apply_changes

DOCUMENT = {
    'summary': 'a result',
    'time_offset': 0.01,
    'time_offset_ns': 10_000_000,
    'extrinsic': {'parent': 'marker', 'child': 'imu', 'translation': [0.0, 0.0, 0.1],
                  'rotation': [0.0, 0.0, 0.0, 1.0]},
}  # fmt: skip


def _session(tmp_path: Path) -> Calibrated:
    staged = tmp_path / 'staged'
    staged.mkdir()
    (staged / 'report.html').write_text(f'<html><head>{REPORT_MARK}</head></html>')
    (staged / 'trajectories.png').write_bytes(b'png')
    document = {**DOCUMENT, 'files': {'report': str(staged / 'report.html')}}
    return Calibrated(document, None, {})


def _disk(root: Path) -> dict[str, tuple[int, bytes | None]]:
    """Every path under ``root``: its mode and, for a file, its content."""
    return {
        str(p): (p.lstat().st_mode, p.read_bytes() if p.is_file() and not p.is_symlink() else None)
        for p in sorted(root.rglob('*'))
    }


@pytest.fixture
def rooms(tmp_path: Path) -> tuple[Path, Path]:
    """output_dir, and a folder outside it with a file and a world-writable sticky folder."""
    out, elsewhere = tmp_path / 'out', tmp_path / 'elsewhere'
    out.mkdir()
    (elsewhere / 'shared').mkdir(parents=True)
    (elsewhere / 'shared').chmod(0o1777)
    (elsewhere / 'precious.yaml').write_text('mine: 1\n')
    (out / 'notes.txt').write_text('my notes\n')
    (out / 'sticky').mkdir()
    (out / 'sticky').chmod(0o1777)
    (out / 'sticky' / 'photo.jpg').write_bytes(b'jpg')
    (out / 'out_link').symlink_to(elsewhere)
    return out, elsewhere


@pytest.mark.parametrize(
    ('key', 'value', 'said'),
    [
        ('output_file', '../elsewhere/precious.yaml', '".." is not allowed'),
        ('output_file', '{elsewhere}/precious.yaml', 'outside output_dir'),
        ('output_file', 'out_link/precious.yaml', 'outside output_dir'),
        ('output_file', 'notes.txt', 'is not a handeye_ros result; refusing to overwrite it'),
        ('output_file', 'sticky', 'is a folder'),
        ('report_dir', 'out_link/shared', 'outside output_dir'),
        ('report_dir', 'sticky', 'holds no handeye_ros report'),
    ],
)
def test_save_refuses_in_one_line_and_changes_nothing(rooms, tmp_path, key, value, said) -> None:
    out, elsewhere = rooms
    session = _session(tmp_path)
    value = value.format(elsewhere=elsewhere)
    cfg = NodeConfig(output_dir=str(out), **{key: value, 'report_dir': 'report'} | {key: value})
    before = _disk(tmp_path)
    ok, message = save(session, cfg)
    assert not ok and said in message and '\n' not in message, message
    assert _disk(tmp_path) == before


def test_save_writes_inside_replaces_its_own_and_keeps_modes(rooms, tmp_path) -> None:
    out, _ = rooms
    session = _session(tmp_path)
    (out / 'empty').mkdir(mode=0o1777)
    (out / 'empty').chmod(0o1777)
    cfg = NodeConfig(output_dir=str(out), output_file='runs/today.yaml', report_dir='empty')
    for _ in range(2):  # the second replaces the first's files: they are ours
        ok, message = save(session, cfg)
        assert ok, message
    assert message == f'wrote {out / "runs/today.yaml"}, {out / "empty/report.html"}'
    assert read_result(out / 'runs/today.yaml')['time_offset'] == 0.01
    assert stat.S_IMODE((out / 'empty').stat().st_mode) == 0o1777
    assert sorted(os.listdir(out / 'empty')) == ['report.html', 'trajectories.png']
    assert stat.S_IMODE((out / 'runs/today.yaml').stat().st_mode) == 0o644


@pytest.mark.parametrize(
    ('value', 'said'),
    [
        ('', 'output_file is empty'),
        ('../evil.yaml', '".." is not allowed'),
        ('/etc/evil.yaml', 'outside output_dir'),
    ],
)
def test_a_path_out_of_output_dir_is_refused_when_set(tmp_path, value, said) -> None:
    cfg = NodeConfig(output_dir=str(tmp_path))
    answer, _, kept = apply_changes(
        [Parameter('output_file', value=value)], CalibrationConfig(), cfg
    )
    assert not answer.successful and said in answer.reason, answer.reason
    assert kept is cfg
