"""Evaluation after a calibration: APE/RPE with and without it, evo-ready exports checked by the
real evo (a test-only dependency, run as the user would run it), and the HTML report checked
in a real headless browser (Debian's chromium) where one is installed.
"""

from __future__ import annotations

import base64
import html
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_cli, run_main

from handeye_ros.core.geometry import compose, matrix_from_quat
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.evaluation.aligned import AlignedTrajectories
from handeye_ros.evaluation.metrics import ape, rpe, rpe_pairs
from handeye_ros.evaluation.outputs import FIGURES
from handeye_ros.formats import read_trajectory, write_tum

pytestmark = pytest.mark.slow  # subprocesses, bags, evo, Dask or real data: seconds each

EVO_BIN = Path(sys.executable).parent
#: evo's statistics are printed from the same float64 poses we write with 9 decimals (1e-9 m);
#: the issue asks for 0.1 mm, the numbers agree far closer.
EVO_TOLERANCE_M = 1e-4


def _ok(res) -> None:
    assert res.returncode == 0, res.stderr
    assert 'Traceback' not in res.stderr


def _evo(tool: str, *args: str, home: Path) -> subprocess.CompletedProcess:
    """Run one of evo's command-line tools in ``home``, its settings kept there too (what it
    saves by name lands there: never in a folder another suite or worker shares)."""
    exe = EVO_BIN / tool
    if not exe.exists():
        pytest.skip(f'{tool} is not installed (evo is a test-only dependency: scripts/setup)')
    home.mkdir(exist_ok=True)
    env = dict(os.environ, HOME=str(home), MPLBACKEND='Agg')
    proc = subprocess.run(
        [str(exe), *args, '--no_warnings'],
        capture_output=True,
        text=True,
        env=env,
        cwd=home,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc


def _evo_stats(zip_path: Path) -> dict:
    with zipfile.ZipFile(zip_path) as z:
        return json.loads(z.read('stats.json'))


@pytest.fixture(scope='module')
def exported(sim_files, tmp_path_factory) -> tuple[dict, Path, Path]:
    """One offline run with --export and --report on the shared simulated recording."""
    hand, eye, _ = sim_files
    out = tmp_path_factory.mktemp('evaluation')
    res = run_cli(
        '--hand',
        hand,
        '--eye',
        eye,
        '--json',
        '--export',
        out / 'export',
        '--report',
        out / 'report',
    )
    _ok(res)
    return json.loads(res.stdout), out, hand


def test_evo_ape_and_rpe_on_our_exports_equal_ours(exported, tmp_path: Path) -> None:
    d, out, _ = exported
    ex = out / 'export'
    ev = d['evaluation']['calibrated']
    _evo(
        'evo_ape',
        'tum',
        str(ex / 'groundtruth.tum'),
        str(ex / 'estimate.tum'),
        '--save_results',
        str(tmp_path / 'ape.zip'),
        home=tmp_path,
    )
    evo_ape = _evo_stats(tmp_path / 'ape.zip')
    for key in ('rmse', 'mean', 'median', 'max'):
        assert abs(evo_ape[key] - ev['ape_translation'][key]) < EVO_TOLERANCE_M, key
    # the same numbers as the calibration's own metrics (the export is what it evaluated)
    assert abs(evo_ape['rmse'] - d['metrics']['ape_rmse']) < EVO_TOLERANCE_M
    _evo(
        'evo_rpe',
        'tum',
        str(ex / 'groundtruth.tum'),
        str(ex / 'estimate.tum'),
        '--delta',
        '1',
        '--delta_unit',
        'm',
        '--all_pairs',
        '--pairs_from_reference',
        '--save_results',
        str(tmp_path / 'rpe.zip'),
        home=tmp_path,
    )
    evo_rpe = _evo_stats(tmp_path / 'rpe.zip')
    assert abs(evo_rpe['rmse'] - ev['rpe_distance_translation']['rmse']) < EVO_TOLERANCE_M


def test_evo_transform_right_applies_our_extrinsic(exported, tmp_path: Path) -> None:
    d, out, hand = exported
    _evo(
        'evo_traj',
        'tum',
        str(hand),
        '--transform_right',
        str(out / 'export' / 'T_HE.json'),
        '--save_as_tum',
        home=tmp_path,
    )
    # evo writes <name>.tum into the working directory of the call
    got = read_trajectory(tmp_path / (Path(hand).stem + '.tum'), 'tum')
    h = read_trajectory(hand, 'tum')
    X = (
        matrix_from_quat(np.asarray(d['extrinsic']['rotation'])),
        np.asarray(d['extrinsic']['translation']),
    )
    R, p = compose((matrix_from_quat(h.q_xyzw), h.p_xyz), X)
    assert np.max(np.abs(got.p_xyz - p)) < 1e-6
    assert np.max(np.abs(matrix_from_quat(got.q_xyzw) - R)) < 1e-6
    he = json.loads((out / 'export' / 'T_HE.json').read_text())
    eh = json.loads((out / 'export' / 'T_EH.json').read_text())
    assert set(he) == set(eh) == {'x', 'y', 'z', 'qx', 'qy', 'qz', 'qw'}


def test_calibration_improves_on_what_users_do_today(exported) -> None:
    d, _, _ = exported
    ev = d['evaluation']
    cal, base = ev['calibrated'], ev['uncalibrated']
    # simulated with a random T_HE (tens of cm, tens of deg) and offset: the baseline's
    # rotation error holds the whole marker-to-body rotation and its RPE the lever arm
    assert base is not None
    assert cal['ape_rotation']['rmse'] < base['ape_rotation']['rmse']
    assert cal['rpe_time_translation']['rmse'] < 0.5 * base['rpe_time_translation']['rmse']
    assert (
        cal['rpe_time_translation']['n']
        > 0.9 * d['inputs']['eye']['duration_s'] * d['inputs']['eye']['rate_hz'] * 0.9
    )


def test_clocks_apart_have_no_baseline_and_say_why(tmp_path: Path, sim_files) -> None:
    hand, _, rec = sim_files
    far = tmp_path / 'eye_far.txt'
    e = rec.eye
    write_tum(far, Trajectory.from_arrays(e.t_ns + 10**15, e.p_xyz, e.q_xyzw, 'far'))
    res = run_main('--hand', hand, '--eye', far, '--json', '--report', tmp_path / 'r')
    _ok(res)
    ev = json.loads(res.stdout)['evaluation']
    assert ev['uncalibrated'] is None
    assert 'clocks do not overlap' in ev['uncalibrated_why']
    assert ev['calibrated']['ape_translation']['n'] > 100
    assert (tmp_path / 'r' / 'report.html').is_file()


def test_a_warning_the_verdict_notes_is_said_once_in_the_report(sim_files) -> None:
    """Clocks on different epochs are a warning and a note of the verdict: the terminal and
    HTML reports say it once, among the notes; a warning the verdict does not say stays."""
    from handeye_ros.core.pipeline import calibrate
    from handeye_ros.evaluation.html import render
    from handeye_ros.evaluation.terminal import format_report

    _, _, rec = sim_files
    e = rec.eye
    boot = e.t_ns - rec.hand.t_ns[0] + 10**11  # the eye on time since boot, the hand on Unix
    d = calibrate(rec.hand, Trajectory.from_arrays(boot, e.p_xyz, e.q_xyzw)).to_dict()
    (epochs,) = [w for w in d['warnings'] if 'epoch' in w]
    assert epochs in d['quality']['notes']
    d['warnings'].append('a warning of its own')
    text = format_report(d)
    assert text.count(epochs) == 1 and f'note: {epochs}' in text
    assert 'WARNING: a warning of its own' in text and f'WARNING: {epochs}' not in text
    page = render(d, [])
    assert page.count(html.escape(epochs)) == 1 and 'a warning of its own' in page


def test_unwritable_output_directory_fails_before_calibrating(sim_files, tmp_path: Path) -> None:
    hand, eye, _ = sim_files
    blocker = tmp_path / 'file'
    blocker.write_text('x')
    for flag in ('--report', '--export'):
        res = run_main('--hand', hand, '--eye', eye, flag, blocker / 'sub')
        assert res.returncode == 1 and 'Traceback' not in res.stderr
        assert res.stderr.startswith(f'offline_calibrate: error: {flag} '), res.stderr
        assert 'cannot write there' in res.stderr
    res = run_main('--hand', hand, '--eye', eye, '--rpe-delta', '-1')
    assert res.returncode == 1 and '--rpe-delta must be a positive number' in res.stderr


def _aligned(p_ref, p_est, t_s, segment=None, R_est=None) -> AlignedTrajectories:
    n = len(t_s)
    eye = np.tile(np.eye(3), (n, 1, 1))
    return AlignedTrajectories(
        np.rint(np.asarray(t_s) * 1e9).astype(np.int64),
        eye,
        p_ref,
        eye if R_est is None else R_est,
        p_est,
        np.zeros(n, int) if segment is None else segment,
        'test',
    )


def test_ape_and_rpe_exact_cases() -> None:
    t = np.arange(101) * 0.1
    p = np.c_[t, np.zeros_like(t), np.zeros_like(t)]  # 1 m/s along x
    # a constant error: APE is its norm, RPE is zero
    al = _aligned(p, p + [0.0, 0.03, 0.04], t)
    assert np.allclose(ape(al)[0], 0.05)
    e_t, e_r, _ = rpe(al, 1.0, 's')
    assert np.allclose(e_t, 0.0) and np.allclose(e_r, 0.0)
    # the estimate 10 % too fast: RPE per 1 s and per 1 m is 0.1 m
    al = _aligned(p, p * 1.1, t)
    e_t, _, i = rpe(al, 1.0, 's')
    assert np.allclose(e_t, 0.1) and i.size == 91
    e_t, _, i = rpe(al, 1.0, 'm')
    _, j = rpe_pairs(al, 1.0, 'm')
    # the nearest pose within 10 % of the step (evo's rule): 0.1 of the path actually spanned
    assert np.allclose(e_t, 0.1 * (t[j] - t[i])) and np.all(np.abs(t[j] - t[i] - 1.0) <= 0.1)
    # no pair joins two segments
    seg = (t >= 5.0).astype(int)
    i, j = rpe_pairs(_aligned(p, p, t, seg), 1.0, 's')
    assert np.all(seg[i] == seg[j]) and i.size == 40 + 41
    with pytest.raises(ValueError, match='positive'):
        rpe_pairs(al, 0.0, 's')


# ----------------------------------------------------------------------------- the report

CHROMIUM = shutil.which('chromium') or shutil.which('chromium-browser')
#: The flags that let headless chromium start as root in a closed network (no GPU, no sandbox,
#: no background connections).
CHROMIUM_FLAGS = (
    '--headless',
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
)
CHECK_SCRIPT = """<script>
window.addEventListener('load', () => {
  const imgs = Array.from(document.images);
  const out = document.createElement('pre');
  out.id = 'image-check';
  out.textContent = JSON.stringify(imgs.map(i => [i.alt, i.complete, i.naturalWidth]));
  document.body.appendChild(out);
});
</script>"""


def test_report_page_holds_every_plot(exported) -> None:
    _, out, _ = exported
    page = out / 'report' / 'report.html'
    text = page.read_text()
    names = re.findall(r'data-file="([^"]+)"', text)
    assert names == [
        'time_alignment.png',
        'clock.png',
        'linear.png',
        'excitation.png',
        'residuals.png',
        'trajectories.png',
    ]
    for name, data in zip(
        names, re.findall(r'src="data:image/png;base64,([^"]+)"', text), strict=True
    ):
        blob = base64.b64decode(data)
        assert blob == (out / 'report' / name).read_bytes()
        assert blob.startswith(b'\x89PNG\r\n\x1a\n')
    assert 'http://' not in text and 'https://' not in text  # nothing to fetch: opens offline
    for needle in (
        'T_HE: eye frame in hand frame',
        'T_EH: hand frame in eye frame',
        'T_WG',
        'APE translation',
        'RPE per 1 s',
        'GOOD',
    ):
        assert needle in text, needle


def test_report_renders_in_a_real_browser(exported, tmp_path: Path) -> None:
    if CHROMIUM is None:
        pytest.skip(
            "chromium is not installed (scripts/browser installs Debian's); the "
            'report was not opened in a browser'
        )
    _, out, _ = exported
    page = tmp_path / 'check.html'
    page.write_text(
        (out / 'report' / 'report.html').read_text().replace('</body>', CHECK_SCRIPT + '</body>')
    )
    args = [CHROMIUM, *CHROMIUM_FLAGS, f'--user-data-dir={tmp_path / "profile"}']
    dom = subprocess.run(
        [*args, '--dump-dom', page.as_uri()],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    found = re.search(r'<pre id="image-check">(.*?)</pre>', dom.stdout, re.DOTALL)
    assert found, dom.stderr[-2000:]
    images = json.loads(found.group(1).replace('&quot;', '"'))
    assert [alt for alt, _, _ in images] == [*FIGURES]
    for alt, complete, width in images:
        assert complete and width > 500, (alt, complete, width)
    shot = tmp_path / 'report.png'
    subprocess.run(
        [*args, f'--screenshot={shot}', '--window-size=1200,3000', page.as_uri()],
        capture_output=True,
        timeout=120,
        check=False,
    )
    assert shot.is_file() and shot.stat().st_size > 20_000
    keep = ROOT / 'bench' / 'out'
    if keep.is_dir():  # for a human to look at; bench/out is not committed
        shutil.copy(shot, keep / 'report_screenshot.png')
