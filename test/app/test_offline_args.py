"""The offline tool's argument cases, its ``main`` run in process (conftest.run_main: the same
exit codes, stdout and stderr as the subprocess of test_offline_cli.py, without the start-up).

Every bad input must give exit code 1 and one clear line naming the file and the problem on
stderr, never a traceback.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import cli_fails, cli_ok, recording, run_main
from scipy.spatial.transform import Rotation

from handeye_ros.core.geometry import compose
from handeye_ros.core.simulate import random_truth
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats import read_trajectory, write_euroc, write_tum


@pytest.mark.slow  # calibrates a 60 s recording, 1-3 s a call
def test_options_and_config_file(sim_files, tmp_path: Path) -> None:
    hand, eye, rec = sim_files
    cfg = tmp_path / 'params.yaml'
    cfg.write_text(
        yaml.safe_dump(
            {
                'calibrator': {
                    'ros__parameters': {
                        'hand_topic': '/mocap',
                        'eta': 8.0,
                        'seed': 3,
                        'mu': 5.0,
                    }
                }
            }
        )
    )
    res = run_main(
        '--hand',
        hand,
        '--eye',
        eye,
        '--json',
        '--config',
        cfg,
        '--eta',
        '6',
        '--ransac-iterations',
        '150',
    )
    cli_ok(res)
    d = json.loads(res.stdout)
    assert d['config']['eta'] == 6.0  # the command line wins over the file
    assert d['config']['seed'] == 3 and d['config']['ransac_iterations'] == 150
    assert 'robust_kernel' not in d['config']  # an ablation switch, at its default
    fixed = run_main(
        '--hand', hand, '--eye', eye, '--json', '--time-offset', str(rec.truth.time_offset_s)
    )
    cli_ok(fixed)
    assert json.loads(fixed.stdout)['time_offset'] == rec.truth.time_offset_s


@pytest.mark.slow  # calibrates a 60 s recording, 1-3 s a call
def test_euroc_input_and_sign_flips(sim_files, tmp_path: Path) -> None:
    """EuRoC CSV (w x y z) hand and quaternion signs flipped on every other row give the same
    result as the TUM files."""
    hand, eye, _ = sim_files
    traj = read_trajectory(hand)
    q = traj.q_xyzw * np.where(np.arange(len(traj)) % 2, -1.0, 1.0)[:, None]
    flipped = Trajectory(traj.t_ns, traj.p_xyz, q, 'flipped')
    csv = tmp_path / 'hand.csv'
    write_euroc(csv, flipped)
    a = run_main('--hand', hand, '--eye', eye, '--json')
    b = run_main('--hand', csv, '--eye', eye, '--json')
    cli_ok(a)
    cli_ok(b)
    da, db = json.loads(a.stdout), json.loads(b.stdout)
    assert db['inputs']['hand']['source'] == str(csv)
    # both files round quaternions to 12 decimals, in different column orders: the two
    # readings differ by ~1e-12 per pose, which moves the sub-sample peak by ~1e-9 s
    assert db['time_offset'] == pytest.approx(da['time_offset'], abs=1e-7)
    np.testing.assert_allclose(
        db['extrinsic']['translation'], da['extrinsic']['translation'], atol=1e-6
    )


@pytest.mark.slow  # calibrates a 60 s recording three times
def test_csv_in_seconds_is_read_in_tum_order(sim_files, tmp_path: Path) -> None:
    """A comma-separated eye in seconds with t, x, y, z, qx, qy, qz, qw (the ETH hand-eye
    tools' CSV) is read in TUM order, says so, and calibrates as the TUM file does; the same
    CSV with w x y z columns is then read the other way round by the convention check, which
    names it (and --eye-quaternion-order states it)."""
    hand, eye, _ = sim_files
    traj = read_trajectory(eye)
    t = [f'{int(v) // 10**9}.{int(v) % 10**9:09d}' for v in traj.t_ns]
    rows = np.column_stack((traj.p_xyz, traj.q_xyzw))
    csv, wxyz = tmp_path / 'eye_xyzw.csv', tmp_path / 'eye_wxyz.csv'
    csv.write_text(
        '# t, x, y, z, qx, qy, qz, qw\n'
        + ''.join(
            f'{s},' + ','.join(f'{v:.12f}' for v in r) + '\n' for s, r in zip(t, rows, strict=True)
        )
    )
    rows = rows[:, [0, 1, 2, 6, 3, 4, 5]]
    wxyz.write_text(
        ''.join(
            f'{s},' + ','.join(f'{v:.12f}' for v in r) + '\n' for s, r in zip(t, rows, strict=True)
        )
    )
    a = json.loads(run_main('--hand', hand, '--eye', eye, '--json').stdout)
    res = run_main('--hand', hand, '--eye', csv, '--json')
    cli_ok(res)
    b = json.loads(res.stdout)
    assert any('read as t, x, y, z, qx, qy, qz, qw' in w for w in b['warnings'])
    assert b['quality']['verdict'] == a['quality']['verdict'] and not b['conventions']
    assert b['time_offset'] == pytest.approx(a['time_offset'], abs=1e-6)
    np.testing.assert_allclose(
        b['extrinsic']['translation'], a['extrinsic']['translation'], atol=1e-5
    )
    res = run_main('--hand', hand, '--eye', wxyz, '--json')
    cli_ok(res)
    c = json.loads(res.stdout)
    assert [x['assumed'] for x in c['conventions']] == ['wxyz']
    assert 'convention_corrected' in [r['code'] for r in c['quality']['reasons']]
    assert c['time_offset'] == pytest.approx(a['time_offset'], abs=1e-4)
    res = run_main('--hand', hand, '--eye', wxyz, '--eye-quaternion-order', 'wxyz', '--json')
    assert not json.loads(res.stdout)['conventions']


BAD_FILES = {
    'empty': ('', 'holds no poses'),
    'one line': ('1403636579.0 0 0 0 0 0 0 1\n', 'holds 1 pose'),
    'unsorted': ('2.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n3.0 0 0 0 0 0 0 1\n', 'unsorted'),
    'duplicate': ('1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n', 'duplicate'),
    'nan': ('1.0 0 0 0 0 0 0 1\n2.0 0 nan 0 0 0 0 1\n', 'NaN or inf'),
    'inf': ('1.0 0 0 0 0 0 0 1\n2.0 0 0 inf 0 0 0 1\n', 'NaN or inf'),
    'zero quaternion': ('1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 0\n', 'zero quaternion'),
    'non-unit quaternion': ('1.0 0 0 0 0 0 0 2\n2.0 0 0 0 0 0 0 1\n', 'non-unit'),
    'unknown format': ('a;b;c\n', 'unknown trajectory format'),
    'binary': ('\x00\x01\x02 garbage\n', 'unknown trajectory format'),
}


@pytest.mark.parametrize('case', sorted(BAD_FILES))
@pytest.mark.parametrize('which', ['hand', 'eye'])
def test_bad_file(sim_files, tmp_path: Path, case: str, which: str) -> None:
    hand, eye, _ = sim_files
    content, message = BAD_FILES[case]
    bad = tmp_path / f'bad_{which}.txt'
    bad.write_text(content)
    args = {'hand': hand, 'eye': eye, which: bad}
    cli_fails(run_main('--hand', args['hand'], '--eye', args['eye']), str(bad), message)


def test_how_files_are_read_is_refused_with_a_bag(tmp_path: Path) -> None:
    """Options that say how trajectory files are read do nothing to a bag's messages (stamps in
    ns, quaternions x y z w by ROS's definition): refused, not silently dropped, before the bag
    is opened."""
    bag = tmp_path / 'any.mcap'
    res = run_main('--bag', bag, '--eye-quaternion-order', 'wxyz', '--hand-stamp-unit', 'us')
    cli_fails(res, '--hand-stamp-unit us, --eye-quaternion-order wxyz', 'not a bag')


def test_missing_file_and_bad_config(sim_files, tmp_path: Path) -> None:
    hand, eye, _ = sim_files
    cli_fails(run_main('--hand', tmp_path / 'nope.txt', '--eye', eye), 'nope.txt', 'no such file')
    cfg = tmp_path / 'c.yaml'
    cfg.write_text('eta: 5\nkernel: on\n')
    cli_fails(run_main('--hand', hand, '--eye', eye, '--config', cfg), 'c.yaml', 'unknown option')
    cfg.write_text('eta: [1, 2\n')
    cli_fails(run_main('--hand', hand, '--eye', eye, '--config', cfg), 'c.yaml', 'not valid YAML')
    cli_fails(run_main('--hand', hand, '--eye', eye, '--eta', '-1'), 'eta must lie in')
    # outputs that cannot go where they are asked to are said before the calibration runs
    cli_fails(
        run_main('--hand', hand, '--eye', eye, '-o', tmp_path / 'no' / 'dir' / 'r.yaml'),
        'cannot write the result (no folder',
    )
    cli_fails(run_main('--hand', hand, '--eye', eye, '-o', tmp_path), 'it is a folder')
    bag = ['--output-bag', tmp_path / 'out', '--output-bag-storage', 'ros1']
    cli_fails(run_main('--hand', hand, '--eye', eye, *bag), 'a ROS 1 bag is one file named')


def test_overlap_too_short(sim_files, tmp_path: Path) -> None:
    hand, eye, _ = sim_files
    lines = Path(eye).read_text().splitlines()
    short = tmp_path / 'short_eye.txt'
    short.write_text('\n'.join(lines[:60]) + '\n')  # 3 s of eye poses
    cli_fails(run_main('--hand', hand, '--eye', short), str(short), 'overlap')


@pytest.mark.slow  # calibrates a 60 s recording, 1-3 s a call
def test_offset_outside_the_window(tmp_path: Path) -> None:
    rec = recording(seed=8, level=1.0)
    hand, eye = tmp_path / 'h.txt', tmp_path / 'e.txt'
    write_tum(hand, rec.hand)
    # the eye clock 0.8 s ahead: found by default (every lag is searched), refused when the
    # window given excludes it, found again when the guess moves the window there
    write_tum(eye, Trajectory(rec.eye.t_ns + 800_000_000, rec.eye.p_xyz, rec.eye.q_xyzw))
    found = run_main('--hand', hand, '--eye', eye, '--json')
    cli_ok(found)
    assert json.loads(found.stdout)['time_offset'] == pytest.approx(
        rec.truth.time_offset_s + 0.8, abs=2e-3
    )
    # the window holds no true peak: either the peak sits at its edge, or a false one inside
    # leaves no consensus in stage 2; both refusals name the window's options
    narrow = run_main('--hand', hand, '--eye', eye, '--max-time-offset', '0.5')
    assert narrow.returncode == 1 and 'time_offset_guess' in narrow.stderr
    assert 'edge of the search window' in narrow.stderr or 'searched in' in narrow.stderr
    d = run_main('--hand', hand, '--eye', eye, '--json', '--time-offset-guess', '0.8')
    cli_ok(d)
    assert json.loads(d.stdout)['time_offset'] == pytest.approx(
        rec.truth.time_offset_s + 0.8, abs=3e-3
    )


def _small_rotation_files(tmp_path: Path) -> tuple[Path, Path]:
    """Rotations of ~1.5 deg amplitude about all axes: speed varies, yet no 5 deg keyframes."""
    t = np.arange(6000) * 0.01
    rv = np.deg2rad(1.5) * np.stack([np.sin(1.1 * t), np.sin(1.7 * t + 1), np.sin(2.3 * t)], 1)
    R = Rotation.from_rotvec(rv).as_matrix()
    p = np.stack([np.sin(0.5 * t), np.cos(0.3 * t), 0.2 * np.sin(t)], axis=1)
    truth = random_truth(np.random.default_rng(1))
    X = (Rotation.from_quat(truth.q_HE).as_matrix(), truth.p_HE)
    Re, pe = compose((R, p), X)
    t_ns = 1_700_000_000 * 10**9 + np.rint(t * 1e9).astype(np.int64)
    hand, eye = tmp_path / 'h.txt', tmp_path / 'e.txt'
    write_tum(hand, Trajectory.from_arrays(t_ns, p, Rotation.from_matrix(R).as_quat()))
    write_tum(
        eye, Trajectory.from_arrays(t_ns[::5], pe[::5], Rotation.from_matrix(Re[::5]).as_quat())
    )
    return hand, eye


def test_too_little_rotation(tmp_path: Path) -> None:
    hand, eye = _small_rotation_files(tmp_path)
    cli_fails(run_main('--hand', hand, '--eye', eye), 'rotates too little', 'eta')


@pytest.mark.slow  # calibrates a 60 s recording, 1-3 s a call
def test_strict_exits_2_unless_good(sim_files, tmp_path: Path) -> None:
    """--strict: 0 for a good verdict; 2 (and the reason codes on stderr) for any other, here
    an eye written w x y z in a TUM file (corrected, but the file still holds the mistake)."""
    hand, eye, _ = sim_files
    cli_ok(run_main('--hand', hand, '--eye', eye, '--strict'))
    traj = read_trajectory(eye)
    swapped = tmp_path / 'eye_wxyz.txt'
    swapped.write_text(
        ''.join(
            f'{t // 10**9}.{t % 10**9:09d} {p[0]} {p[1]} {p[2]} {q[3]} {q[0]} {q[1]} {q[2]}\n'
            for t, p, q in zip(traj.t_ns, traj.p_xyz, traj.q_xyzw, strict=True)
        )
    )
    res = run_main('--hand', hand, '--eye', swapped, '--strict')
    assert res.returncode == 2 and 'convention_corrected' in res.stderr, res.stderr
    assert 'VERDICT: DOUBTFUL' in res.stdout
    # stating the file's order explicitly: nothing to correct, good again
    cli_ok(
        run_main('--hand', hand, '--eye', swapped, '--eye-quaternion-order', 'wxyz', '--strict')
    )


@pytest.mark.slow  # calibrates a 60 s recording, 1-3 s a call
def test_binary_config_and_unwritable_bag_stamps(sim_files, tmp_path: Path) -> None:
    hand, eye, rec = sim_files
    blob = tmp_path / 'options.bin'
    blob.write_bytes(bytes(range(256)) * 4)
    cli_fails(run_main('--hand', hand, '--eye', eye, '--config', blob), 'not a text file')
    # stamps in 2065: fine for int64 ns and the calibration, not for a ROS time (int32 s)
    late = 3_000_000_000 * 10**9 - rec.hand.t_ns[0]
    h2, e2 = tmp_path / 'h.txt', tmp_path / 'e.txt'
    write_tum(h2, rec.hand.shifted(late))
    write_tum(e2, rec.eye.shifted(late))
    cli_fails(
        run_main('--hand', h2, '--eye', e2, '--output-bag', tmp_path / 'out'),
        'no ROS time',
        'int32',
    )
