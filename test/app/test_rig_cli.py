"""One rig, many recordings from the command line: ``offline_calibrate --rig`` and ``evaluate
--shared-extrinsic`` (on a real LocalCluster), with the bad manifests a user writes."""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import cli_fails, cli_ok, recording, run_cli, run_main
from scipy.spatial.transform import Rotation

from handeye_ros.core.simulate import random_truth
from handeye_ros.formats import write_tum
from handeye_ros.formats.result_file import read_result

pytestmark = pytest.mark.slow  # recordings calibrated in turn: seconds


@pytest.fixture(scope='module')
def rig(tmp_path_factory) -> tuple[Path, object]:
    """Four recordings of one marker (level 3, 40 s, each its own clock and world), one whose
    hand file is missing, one whose hand is another body (another recording's MoCap), and one
    whose marker was turned by 3 deg."""
    folder = tmp_path_factory.mktemp('rig')
    base = random_truth(np.random.default_rng(11))
    runs = []
    for k in range(5):
        truth = replace(
            random_truth(np.random.default_rng([11, k])), q_HE=base.q_HE, p_HE=base.p_HE
        )
        if k == 4:
            turned = Rotation.from_quat(base.q_HE) * Rotation.from_rotvec([0.0, 0.0, 0.05])
            truth = replace(truth, q_HE=turned.as_quat())
        rec = recording(seed=300 + k, level=3.0, duration_s=40.0, truth=truth)
        write_tum(folder / f'hand{k}.txt', rec.hand)
        write_tum(folder / f'eye{k}.txt', rec.eye)
        runs.append({'name': f'rec{k}', 'hand': f'hand{k}.txt', 'eye': f'eye{k}.txt'})
    runs[4]['name'] = 'turned'
    runs.append({'name': 'missing', 'hand': 'nowhere.txt', 'eye': 'eye0.txt'})
    other = recording(seed=399, level=3.0, duration_s=40.0)
    write_tum(folder / 'other_body.txt', other.hand)
    runs.append({'name': 'other body', 'hand': 'other_body.txt', 'eye': 'eye1.txt'})
    path = folder / 'rig.yaml'
    path.write_text(yaml.safe_dump({'runs': runs}))
    return path, base


def test_offline_rig_names_what_it_leaves_out_and_exports_each_at_the_rigs_extrinsic(
    rig, tmp_path: Path
) -> None:
    manifest, base = rig
    res = run_main(
        '--rig',
        manifest,
        '--export',
        tmp_path / 'out',
        '-o',
        tmp_path / 'rig.yaml',
        '--report',
        tmp_path / 'page',
    )
    cli_ok(res)
    page = (tmp_path / 'page' / 'rig.html').read_text()
    assert 'data:image/png;base64,' in page and page.count('<tr>') == 1 + 7
    assert 'left out' in page and 'no such file' in page
    assert res.stdout.startswith('rig: doubtful (4 of 7 recordings)'), res.stdout
    doc = yaml.safe_load((tmp_path / 'rig.yaml').read_text())
    r = doc['rig']
    assert r['used'] == ['rec0', 'rec1', 'rec2', 'rec3']
    assert set(r['left_out']) == {'turned', 'missing', 'other body'}
    assert 'no such file' in r['left_out']['missing']
    assert (
        '3.0' in r['left_out']['turned'] or 'deg from the 4 that agree' in r['left_out']['turned']
    )
    # the rig's T_HE: level 3 noise, 4 x 40 s: within a few mm and a tenth of a degree
    assert np.linalg.norm(np.subtract(r['extrinsic']['translation'], base.p_HE)) < 0.006
    turn = Rotation.from_quat(r['extrinsic']['rotation']).inv() * Rotation.from_quat(base.q_HE)
    assert np.degrees(turn.magnitude()) < 0.15
    # each used recording: its result file at the rig's T_HE, its own values kept beside
    one = read_result(tmp_path / 'out' / 'runs' / 'rec0' / 'result.yaml')
    assert one['extrinsic']['translation'] == pytest.approx(r['extrinsic']['translation'])
    assert one['rig']['own']['translation'] != one['extrinsic']['translation']
    assert (tmp_path / 'out' / 'runs' / 'rec0' / 'export' / 'groundtruth.tum').is_file()
    # the turned marker keeps its own result, evaluated with its own T_HE
    own = read_result(tmp_path / 'out' / 'runs' / 'turned' / 'result.yaml')
    assert 'rig' not in own
    assert not (tmp_path / 'out' / 'runs' / 'missing').exists()


def test_bad_rig_manifests_are_refused_with_the_reason(rig, tmp_path: Path) -> None:
    manifest, _ = rig
    one = tmp_path / 'one.yaml'
    runs = yaml.safe_load(manifest.read_text())['runs'][:1]
    for r in runs:
        r['hand'] = str(manifest.parent / r['hand'])
        r['eye'] = str(manifest.parent / r['eye'])
    one.write_text(yaml.safe_dump({'runs': runs}))
    cli_fails(run_main('--rig', one), 'a rig needs at least two recordings, it has 1')
    cli_fails(run_main('--rig', manifest, '--hand', 'x.txt'), 'give no --hand, --eye or --bag')
    cli_fails(run_main('--rig', tmp_path / 'absent.yaml'), 'no such manifest')


def test_evaluate_shared_extrinsic_on_dask_matches_the_sequential_run(rig, tmp_path: Path) -> None:
    manifest, _ = rig
    tables = {}
    for how in ('--sequential', '--workers=2'):
        out = tmp_path / how.strip('-').split('=')[0]
        res = run_cli(
            manifest,
            '-o',
            out,
            '--shared-extrinsic',
            how,
            module='handeye_ros.evaluate',
            timeout=300,
        )
        assert 'Traceback' not in res.stderr, res.stderr
        assert res.returncode == 2, res.stderr  # the missing file's and the other body's rows
        assert 'rig: doubtful (4 of 7 recordings)' in res.stdout
        with (out / 'results.csv').open() as f:
            tables[how] = list(csv.DictReader(f))
        assert (out / 'rig.yaml').is_file() and (out / 'rig.html').is_file()
    seq, dask = tables.values()
    assert [r['rig'] for r in seq] == [r['rig'] for r in dask]
    assert [r['rig'] for r in seq][:4] == ['used'] * 4
    assert seq[5]['status'] == 'failed' and 'no such file' in seq[5]['reason']
    assert seq[6]['status'] == 'failed' and 'RANSAC found no model' in seq[6]['reason']
    assert [r['time_offset_ms'] for r in seq] == [r['time_offset_ms'] for r in dask]
    assert [r['tx_m'] for r in seq[:4]] == [seq[0]['tx_m']] * 4


def test_a_ground_robots_rig_holds_the_lever_arm_it_cannot_see(tmp_path: Path) -> None:
    """Three 60-s recordings of one marker on a ground robot (yaw only, level 3), each its own
    clock and world: every one joins the rig on what it determines, the rig's T_HE is the
    truth within its 3 sigmas there and holds the lever arm along the axis at 0. Good for
    the evaluation (the recordings' figures settled at the rig's T_HE); with purpose
    extrinsic, unobservable."""
    base = random_truth(np.random.default_rng(21))
    runs = []
    for k in range(3):
        truth = replace(
            random_truth(np.random.default_rng([21, k])), q_HE=base.q_HE, p_HE=base.p_HE
        )
        rec = recording(seed=600 + k, level=3.0, duration_s=60.0, truth=truth, motion='planar')
        write_tum(tmp_path / f'hand{k}.txt', rec.hand)
        write_tum(tmp_path / f'eye{k}.txt', rec.eye)
        runs.append({'name': f'ground{k}', 'hand': f'hand{k}.txt', 'eye': f'eye{k}.txt'})
    for purpose, said in (('evaluation', 'good'), ('extrinsic', 'doubtful')):
        manifest = tmp_path / f'{purpose}.yaml'
        manifest.write_text(yaml.safe_dump({'defaults': {'purpose': purpose}, 'runs': runs}))
        res = run_main('--rig', manifest, '-o', tmp_path / f'{purpose}-rig.yaml')
        cli_ok(res)
        assert res.stdout.startswith(f'rig: {said} (3 of 3 recordings)'), res.stdout
        assert 'note: held: the translation along [' in res.stdout
        r = yaml.safe_load((tmp_path / f'{purpose}-rig.yaml').read_text())['rig']
        assert r['used'] == ['ground0', 'ground1', 'ground2']
        assert r['quality']['for_evaluation'] == {
            'verdict': 'good',
            'codes': [],
            'figures_judged': True,
        }
        assert r['quality']['for_extrinsic']['codes'] == ['unobservable']
    # the axis is the hand's z here: the lever arm along it held at 0, the rest the truth's
    sd = np.asarray(r['extrinsic']['std']['translation'])
    err = np.subtract(r['extrinsic']['translation'], base.p_HE)
    assert r['extrinsic']['translation'][2] == pytest.approx(0.0, abs=1e-9)
    assert np.all(np.abs(err[:2]) < 3 * sd[:2]) and sd[2] < 1e-9
    turn = Rotation.from_quat(r['extrinsic']['rotation']).inv() * Rotation.from_quat(base.q_HE)
    assert np.degrees(turn.magnitude()) < 3 * np.degrees(
        np.linalg.norm(r['extrinsic']['std']['rotation'])
    )


def _own(name: str, seed: int, truth) -> object:
    from handeye_ros.app.rig import Own
    from handeye_ros.core.pipeline import calibrate

    rec = recording(seed=seed, level=3.0, duration_s=40.0, truth=truth)
    result = calibrate(rec.hand, rec.eye)
    return Own(name, result.to_dict(), result)


def test_the_nodes_rig_file_grows_by_session_and_names_a_moved_marker(tmp_path: Path) -> None:
    """join_rig, the node's worker step with rig_file: the first session is a rig of one; a
    second of the same marker joins it (the result at the rig's T_HE); calibrating a session
    again replaces its entry; a session of another marker is left out and keeps its own T_HE;
    a file that is no rig file is refused."""
    from handeye_ros.app.rig import join_rig
    from handeye_ros.core.errors import ConfigError
    from handeye_ros.evaluation.outputs import evaluate_and_write

    base = random_truth(np.random.default_rng(21))
    same = [
        replace(random_truth(np.random.default_rng([21, k])), q_HE=base.q_HE, p_HE=base.p_HE)
        for k in range(2)
    ]
    path = tmp_path / 'rigs' / 'lab.yaml'
    path.parent.mkdir()
    first = _own('session 1', 501, same[0])
    doc, result = join_rig(str(path), 'session 1', first)
    assert doc['rig']['part'] == 'used' and doc['rig']['recordings'] == 1
    assert doc['rig']['verdict'] == 'good'
    np.testing.assert_allclose(result.p_HE, first.result.p_HE, atol=1e-12)

    second = _own('session 2', 502, same[1])
    for _ in range(2):  # the second call replaces the session's entry
        doc, result = join_rig(str(path), 'session 2', second)
        assert doc['rig']['part'] == 'used' and doc['rig']['recordings'] == 2
    # evaluated at the rig's T_HE (as the node's worker does): the rig is judged on this
    # session's figures, the earlier session's poses being gone
    doc, result = join_rig(str(path), 'session 2', second, lambda d, r: evaluate_and_write(r, d))
    assert 'evaluation' in doc and doc['rig']['verdict'] == 'good'
    q = yaml.safe_load(path.read_text())['rig']['quality']
    assert q['for_evaluation']['figures_judged'] and q['for_evaluation']['verdict'] == 'good'
    assert 'judged for 1 of the 2 recordings that take it' in q['notes'][0]
    saved = yaml.safe_load(path.read_text())
    assert [r['name'] for r in saved['recordings']] == ['session 1', 'session 2']
    np.testing.assert_allclose(result.p_HE, saved['rig']['extrinsic']['translation'])
    assert 'T_HE of the rig of 2 recordings (lab.yaml)' in doc['summary']

    moved = replace(same[0], p_HE=base.p_HE + [0.05, 0.0, 0.0])
    third = _own('session 3', 503, moved)
    doc, result = join_rig(str(path), 'session 3', third)
    assert doc['rig']['part'] == 'left out' and doc['rig']['verdict'] == 'doubtful'
    np.testing.assert_allclose(result.p_HE, third.result.p_HE, atol=1e-12)
    assert 'left out of the rig (lab.yaml)' in doc['summary']

    bad = tmp_path / 'not_a_rig.yaml'
    bad.write_text('time_offset: 0.1\n')
    with pytest.raises(ConfigError, match=r"not a rig file \(no rig's recordings in it\)"):
        join_rig(str(bad), 'session 1', first)
