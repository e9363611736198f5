"""Trajectory validation and the TUM / EuRoC readers and writers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import recording

from handeye_ros.core.errors import InputError
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats import read_trajectory, write_euroc, write_tum
from handeye_ros.formats.text import detect_format

EPOCH = 1_403_636_579_758_555_555  # a EuRoC-like stamp: float64 seconds cannot hold it exactly


def _traj(n: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = EPOCH + np.arange(n, dtype=np.int64) * 5_000_000
    p = np.arange(3 * n, dtype=float).reshape(n, 3)
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    return t, p, q


@pytest.mark.parametrize(
    ('mutate', 'message'),
    [
        (lambda t, p, q: (t[:1], p[:1], q[:1]), 'holds 1 pose'),
        (lambda t, p, q: (t[[0, 2, 1, 3, 4]], p, q), 'unsorted'),
        (lambda t, p, q: (t[[0, 1, 1, 3, 4]], p, q), 'duplicate'),
        (lambda t, p, q: (t, np.where(np.arange(5)[:, None] == 3, np.nan, p), q), 'NaN or inf'),
        (lambda t, p, q: (t, np.where(np.arange(5)[:, None] == 2, np.inf, p), q), 'NaN or inf'),
        (lambda t, p, q: (t, p, np.where(np.arange(5)[:, None] == 1, 0.0, q)), 'zero quaternion'),
        (lambda t, p, q: (t, p, q * 1.5), 'non-unit'),
        (lambda t, p, q: (t.astype(float), p, q), 'integer nanoseconds'),
    ],
)
def test_trajectory_refuses_bad_arrays(mutate, message: str) -> None:
    with pytest.raises(InputError, match=message) as err:
        Trajectory.from_arrays(*mutate(*_traj()), name='stream.txt')
    assert 'stream.txt' in str(err.value)


def test_quaternion_sign_flips_are_removed() -> None:
    t, p, q = _traj(6)
    q[:] = [0.0, 0.0, np.sin(0.1), np.cos(0.1)]
    q[[1, 4]] *= -1.0
    traj = Trajectory.from_arrays(t, p, q)
    assert np.all(np.einsum('ij,ij->i', traj.q_xyzw[1:], traj.q_xyzw[:-1]) > 0.99)
    np.testing.assert_allclose(np.abs(traj.q_xyzw), np.abs(q))


def test_tum_round_trip_keeps_stamps_exact(tmp_path: Path) -> None:
    rec = recording(seed=1, level=2.0, duration_s=10.0)
    path = tmp_path / 'hand.txt'
    write_tum(path, rec.hand)
    back = read_trajectory(path)
    assert detect_format(path) == 'tum'
    np.testing.assert_array_equal(back.t_ns, rec.hand.t_ns)
    np.testing.assert_allclose(back.p_xyz, rec.hand.p_xyz, atol=1e-9)
    np.testing.assert_allclose(back.q_xyzw, rec.hand.q_xyzw, atol=1e-11)


def test_euroc_round_trip_converts_wxyz(tmp_path: Path) -> None:
    rec = recording(seed=2, duration_s=10.0)
    path = tmp_path / 'gt.csv'
    write_euroc(path, rec.eye)
    first = path.read_text().splitlines()[1].split(',')
    np.testing.assert_allclose(
        [float(v) for v in first[4:8]], rec.eye.q_xyzw[0, [3, 0, 1, 2]], atol=1e-11
    )
    back = read_trajectory(path)
    assert detect_format(path) == 'euroc'
    np.testing.assert_array_equal(back.t_ns, rec.eye.t_ns)
    np.testing.assert_allclose(back.q_xyzw, rec.eye.q_xyzw, atol=1e-11)


def test_euroc_extra_columns_are_ignored(tmp_path: Path) -> None:
    path = tmp_path / 'gt.csv'
    path.write_text(
        '#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z,v_x,v_y,v_z\n'
        f'{EPOCH},1,2,3,1,0,0,0,9,9,9\n'
        f'{EPOCH + 5_000_000},1,2,3,0,1,0,0,9,9,9\n'
    )
    traj = read_trajectory(path)
    np.testing.assert_array_equal(traj.t_ns, [EPOCH, EPOCH + 5_000_000])
    np.testing.assert_allclose(traj.q_xyzw, [[0, 0, 0, 1], [1, 0, 0, 0]])


@pytest.mark.parametrize(
    ('token', 'ns'),
    [
        ('1403636579.758555555', EPOCH),
        ('1403636579.7585555', 1_403_636_579_758_555_500),
        ('1403636579', 1_403_636_579_000_000_000),
        ('1.403636579758555555e9', EPOCH),
        (str(EPOCH), EPOCH),  # integer nanoseconds in a TUM file
    ],
)
def test_tum_stamps_are_parsed_exactly(tmp_path: Path, token: str, ns: int) -> None:
    path = tmp_path / 'traj.txt'
    later = '1403636600.0' if 'e' in token or '.' in token else str(int(token) + 1)
    path.write_text(f'# comment\n{token} 0 0 0 0 0 0 1\n\n{later} 0 0 0 0 0 0 1\n')
    assert read_trajectory(path).t_ns[0] == ns


@pytest.mark.parametrize(
    ('content', 'message'),
    [
        ('', 'holds no poses'),
        ('# only a comment\n', 'holds no poses'),
        ('1.0 0 0 0 0 0 0 1\n', 'holds 1 pose'),
        ('1.0 0 0 0 0 0 0 1\n0.5 0 0 0 0 0 0 1\n', 'unsorted'),
        # half the rows repeat a stamp: stamps with too few digits
        ('1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n', 'repeat the stamp of the row before'),
        ('1.0 0 0 0 0 0 0 1\n2.0 nan 0 0 0 0 0 1\n', 'NaN or inf'),
        ('1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 0\n', 'zero quaternion'),
        ('1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0.5 0 0 0.5\n', 'non-unit'),
        ('1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n', 'line 2: 7 columns'),
        ('1.0 0 0 0 0 0 0 1\n2.0 0 0 x 0 0 0 1\n', "'x' is not a number$"),
        # a header row without its comment mark: said as one
        ('t x y z qx qy qz qw\n1.0 0 0 0 0 0 0 1\n', r'a header row\? start it with #'),
        ('hello world\n', 'unknown trajectory format'),
        ('1,2,3\n', 'unknown trajectory format'),
        ('1e300 0 0 0 0 0 0 1\n2e300 0 0 0 0 0 0 1\n', 'beyond what int64 nanoseconds'),
        ('1,0,0,0,1,0,0,0\n99999999999999999999,0,0,0,1,0,0,0\n', 'beyond what int64'),
    ],
)
def test_bad_files_name_the_file_and_problem(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / 'bad.txt'
    path.write_text(content)
    with pytest.raises(InputError, match=message) as err:
        read_trajectory(path)
    assert str(path) in str(err.value)


def test_missing_file_and_unknown_format(tmp_path: Path) -> None:
    with pytest.raises(InputError, match='no such file'):
        read_trajectory(tmp_path / 'absent.txt')
    with pytest.raises(InputError, match='is a directory'):
        read_trajectory(tmp_path)
    (tmp_path / 'a.txt').write_text('1.0 0 0 0 0 0 0 1\n')
    with pytest.raises(InputError, match='unknown format'):
        read_trajectory(tmp_path / 'a.txt', 'kitti')


def test_repeated_stamps_keep_the_last_row_with_a_note(tmp_path: Path) -> None:
    """Estimators that correct a pose write it again under the same stamp: the later row
    wins and the notes count the repeats."""
    path = tmp_path / 'est.txt'
    rows = [f'{k}.0 {k} 0 0 0 0 0 1\n' for k in range(1, 11)]
    path.write_text(''.join(rows[:2]) + '2.0 -2 0 0 0 0 0 1\n' + ''.join(rows[2:]))
    traj = read_trajectory(path)
    np.testing.assert_array_equal(traj.p_xyz[:, 0], [1.0, -2.0, *range(3, 11)])
    assert any('1 stamp(s) written twice' in n for n in traj.notes)


def test_stamps_with_too_few_digits_are_refused(tmp_path: Path) -> None:
    """A writer's 6-digit default prints every stamp of a recording as 1.7e+09: the poses
    cannot be told apart, and the message says why, not that one pose is left."""
    path = tmp_path / 'est.txt'
    path.write_text(''.join(f'1.7e+09 {k} 0 0 0 0 0 1\n' for k in range(100)))
    with pytest.raises(InputError, match='99 of 100 rows repeat .* too few digits'):
        read_trajectory(path)


@pytest.mark.parametrize(
    ('text', 'unit', 'ns', 'note'),
    [
        # EuRoC with fractional stamps: they cannot be nanoseconds, so seconds
        ('1.5,0,0,0,1,0,0,0\n2.5,0,0,0,1,0,0,0\n', 'auto', 1_500_000_000, 'fractional'),
        # Unix milliseconds in a TUM file cannot be seconds (year 45 000 is beyond int64 ns)
        (
            '1403636579758.555 0 0 0 0 0 0 1\n1403636579808.555 0 0 0 0 0 0 1\n',
            'auto',
            1_403_636_579_758_555_000,
            'read as ms',
        ),
        # stated explicitly: no note
        (
            '1403636579758.555 0 0 0 0 0 0 1\n1403636579808.555 0 0 0 0 0 0 1\n',
            'ms',
            1_403_636_579_758_555_000,
            None,
        ),
        ('1000 0 0 0 0 0 0 1\n1005 0 0 0 0 0 0 1\n', 'us', 1_000_000, None),
        # Unix seconds divided by 1e9 in exponent form (TUM-VI room1 as published): every digit
        # kept, the 18 fractional ones included (the bulk reader's plain-decimal layout too)
        (
            ''.join(f'1.52053030{k}199447678e+00 0 0 0 0 0 0 1\n' for k in range(3)),
            'auto',
            1_520_530_300_199_447_678,
            'read as units of 1e9 s',
        ),
        (
            ''.join(f'1.52053030{k}199447678 0 0 0 0 0 0 1\n' for k in range(3)),
            'auto',
            1_520_530_300_199_447_678,
            'read as units of 1e9 s',
        ),
        (
            '1.520530300199447678 0 0 0 0 0 0 1\n2.6 0 0 0 0 0 0 1\n',
            'Gs',
            1_520_530_300_199_447_678,
            None,
        ),
        # a recording that starts near 1 s in seconds is seconds (its rate is plausible)
        (
            '1.5 0 0 0 0 0 0 1\n1.55 0 0 0 0 0 0 1\n1.6 0 0 0 0 0 0 1\n',
            'auto',
            1_500_000_000,
            None,
        ),
    ],
)
def test_stamp_units(tmp_path: Path, text: str, unit: str, ns: int, note: str | None) -> None:
    path = tmp_path / 'traj.txt'
    path.write_text(text)
    traj = read_trajectory(path, stamp_unit=unit)
    assert traj.t_ns[0] == ns
    assert (note is None and not traj.notes) or any(note in n for n in traj.notes)


def test_quaternion_order_option(tmp_path: Path) -> None:
    """The same rotation written x y z w (TUM's order) and w x y z, read with the option."""
    q = [0.1, 0.2, 0.3, 0.9273618495495703]
    a, b = tmp_path / 'a.txt', tmp_path / 'b.txt'
    a.write_text(f'1.0 0 0 0 {q[0]} {q[1]} {q[2]} {q[3]}\n2.0 0 0 0 0 0 0 1\n')
    b.write_text(f'1.0 0 0 0 {q[3]} {q[0]} {q[1]} {q[2]}\n2.0 0 0 0 1 0 0 0\n')
    np.testing.assert_allclose(
        read_trajectory(a).q_xyzw, read_trajectory(b, quaternion_order='wxyz').q_xyzw, atol=1e-12
    )


def test_a_few_rows_no_stream_can_hold_are_dropped(tmp_path: Path) -> None:
    """A first row with every value multiplied by 1e9 (seen in a published Basalt file): the
    row is dropped and named, the unit is still seconds (chosen on the median stamp), and the
    rest reads as it should. More such rows than 1 % and the file is refused."""
    rows = [f'{100 + 0.05 * k:.2f} {0.01 * k} 0 0 0 0 0 1' for k in range(300)]
    scaled = '1.0e11 1e7 0 0 0 0 0 1e9'
    path = tmp_path / 'est.txt'
    path.write_text('\n'.join([scaled] + rows) + '\n')
    traj = read_trajectory(path)
    assert len(traj) == 300 and traj.t_ns[0] == 100 * 10**9
    assert any('dropped 1 row(s)' in n and 'line(s) 1' in n for n in traj.notes)
    path.write_text('\n'.join([scaled] * 5 + rows) + '\n')
    with pytest.raises(InputError, match='line 1'):
        read_trajectory(path)


@pytest.mark.parametrize(
    'content', ['1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n', '1,0,0,0,1,0,0,0\n2,1,0,0,1,0,0,0\n']
)
def test_a_byte_order_mark_is_read_past(tmp_path: Path, content: str) -> None:
    """Some Windows tools start UTF-8 text with a byte-order mark: the poses are the same."""
    plain, marked = tmp_path / 'plain.txt', tmp_path / 'marked.txt'
    plain.write_text(content)
    marked.write_bytes(b'\xef\xbb\xbf' + content.encode())
    a, b = read_trajectory(plain), read_trajectory(marked)
    np.testing.assert_array_equal(a.t_ns, b.t_ns)
    np.testing.assert_array_equal(a.p_xyz, b.p_xyz)


def test_an_archive_is_said_as_one(tmp_path: Path) -> None:
    """A trajectory file shipped compressed (hand.txt.gz) is named as the archive it is."""
    import gzip

    path = tmp_path / 'eye.txt.gz'
    path.write_bytes(gzip.compress(b'1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n'))
    with pytest.raises(InputError, match='a gzip archive, not a trajectory file: unpack it'):
        read_trajectory(path)
