"""Helpers shared by the benchmarks: output folder, tables, plots, error summaries."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

try:
    import cv2
except ImportError:  # benchmark-only extra (pip install .[bench])
    cv2 = None

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / 'bench' / 'out'
if str(ROOT) not in sys.path:  # run as `python bench/x.py` from anywhere
    sys.path.insert(0, str(ROOT))


def table(title: str, header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A plain-text table (also written to bench/out/<title>.txt by :func:`emit`)."""
    cells = [[str(c) for c in header]] + [[_fmt(c) for c in row] for row in rows]
    widths = [max(len(r[k]) for r in cells) for k in range(len(header))]
    lines = [
        title,
        '  '.join(h.rjust(w) for h, w in zip(cells[0], widths, strict=True)),
        '  '.join('-' * w for w in widths),
    ]
    lines += ['  '.join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in cells[1:]]
    return '\n'.join(lines)


def provenance(seeds: object = None) -> str:
    """One line saying what produced a figure: commit (and whether the tree was dirty), the
    versions of Python and the numerical packages, and the seeds."""
    import platform
    import subprocess

    import scipy

    def git(*args: str) -> str:
        try:
            return subprocess.run(
                ['git', *args], cwd=ROOT, capture_output=True, text=True, check=False, timeout=10
            ).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ''

    commit = git('rev-parse', '--short=12', 'HEAD') or 'unknown'
    # the tables' own documents, which bench/results.py refills while a run goes on, are no
    # change of what printed them
    changed = git(
        'status',
        '--porcelain',
        '--untracked-files=no',
        '--',
        '.',
        ':!bench/results',
        ':!bench/RESULTS.md',
    )
    dirty = ' +uncommitted changes' if changed else ''
    line = (
        f'commit {commit}{dirty}; python {platform.python_version()}, numpy '
        f'{np.__version__}, scipy {scipy.__version__}'
    )
    return line + (f'; seeds {seeds}' if seeds is not None else '')


def emit(name: str, text: str, seeds: object = None) -> None:
    """Print a table with its provenance line and keep a copy in bench/out/."""
    text = f'{text}\n({provenance(seeds)})'
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f'{name}.txt').write_text(text + '\n')
    print(text + '\n', flush=True)


def save_plot(fig, name: str) -> Path:
    """Save a matplotlib figure as bench/out/<name>.png."""
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f'{name}.png'
    fig.savefig(path, dpi=120, bbox_inches='tight')
    return path


def pyplot():
    """matplotlib.pyplot on the Agg backend, or None when matplotlib is not installed."""
    try:
        import matplotlib
    except ImportError:
        print('(matplotlib not installed: no plots)', file=sys.stderr)
        return None
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def _fmt(c: object) -> str:
    if isinstance(c, (float, np.floating)):
        return f'{c:.3f}' if abs(c) < 1000 else f'{c:.0f}'
    return str(c)


#: chi^2 with 3 degrees of freedom at 99.73 %: the 3-sigma of a 3-vector.
CHI2_3_9973 = 14.156


def covered(res, truth, white: bool = False) -> tuple[bool, bool, bool]:
    """Whether the truth lies inside the reported 3-sigma: ``|dt error| <= 3 sigma`` and the
    Mahalanobis distances of the translation and rotation 3-vector errors within chi^2(3)'s
    99.73 % quantile. ``white``: the batch stage's white covariance instead of the long-run
    one."""
    from scipy.spatial.transform import Rotation

    cov = res.batch.covariance_white if white else res.batch.covariance
    e_dt = res.time_offset_s - truth.time_offset_s
    e_t = truth.p_HE - res.p_HE
    # rotation error in the tangent of the estimate: R_true = R_est Exp(e_r)
    e_r = (Rotation.from_quat(res.q_HE).inv() * Rotation.from_quat(truth.q_HE)).as_rotvec()
    m_t = float(e_t @ np.linalg.solve(cov[1:4, 1:4], e_t))
    m_r = float(e_r @ np.linalg.solve(cov[4:7, 4:7], e_r))
    return abs(e_dt) <= 3 * np.sqrt(cov[0, 0]), m_t <= CHI2_3_9973, m_r <= CHI2_3_9973


def sim3_scale(gt, est) -> float:
    """The VIO's own scale error on a real pair: s with s * eye positions closest to the
    ground truth's (both in the IMU frame, same clock) after the best rotation and translation
    (least squares over the matched positions; Umeyama 1991)."""
    from handeye_ros.core.association import associate

    pairs = associate(gt, est, 0.0)
    a = pairs.p_GH - pairs.p_GH.mean(axis=0)
    b = pairs.p_WE - pairs.p_WE.mean(axis=0)
    U, S, Vt = np.linalg.svd(b.T @ a)
    d = np.ones(3)
    d[2] = np.sign(np.linalg.det(U @ Vt))
    # a ~ s R b: the least-squares s of the rotated, centred positions
    return float(np.sum(S * d) / np.sum(b * b))


#: OpenCV's calibrateHandEye methods, the baselines.
OPENCV_METHODS = ('TSAI', 'PARK', 'HORAUD', 'ANDREFF', 'DANIILIDIS')


def opencv_inputs(pairs) -> dict[str, np.ndarray]:
    """The pose pairs OpenCV is fed, two ways: the rotation-constrained keyframe poses (>= 5 deg
    apart) that our linear stage uses, and the poses every 0.5 s."""
    from handeye_ros.core.linear.keyframes import rotation_keyframes

    i, j = rotation_keyframes(pairs.R_GH, np.deg2rad(5.0))
    step = max(1, round(0.5 / np.median(np.diff(pairs.t_eye_s))))
    return {
        'keyframes': np.unique(np.concatenate((i, j))),
        'every 0.5 s': np.arange(0, pairs.t_eye_s.size, step),
    }


def opencv_hand_eye(pairs, idx: np.ndarray, method: str) -> tuple[np.ndarray, np.ndarray]:
    """T_HE by cv2.calibrateHandEye from the pairs at ``idx``.

    OpenCV's eye-in-hand names: gripper = H in base = G (our hand pose T_GH); target = W seen
    from cam = E (T_EW = T_WE^-1); the result cam2gripper is T_HE.
    """
    from handeye_ros.core.geometry import inverse, quat_from_matrix

    R_EW, p_EW = inverse((pairs.R_WE[idx], pairs.p_WE[idx]))
    R, t = cv2.calibrateHandEye(
        list(pairs.R_GH[idx]),
        list(pairs.p_GH[idx]),
        list(R_EW),
        list(p_EW),
        method=getattr(cv2, f'CALIB_HAND_EYE_{method}'),
    )
    if not (np.isfinite(R).all() and np.isfinite(t).all()):  # a failed method: NaN result
        return np.array([0.0, 0.0, 0.0, 1.0]), np.full(3, np.inf)
    return quat_from_matrix(R), t.ravel()


#: The APE figures whose value at another calibration :func:`truth_within` measures.
APE_KEYS = ('ape_translation', 'ape_rotation')


def judged(res):
    """(the result with its figures judged, as every front end judges it for purpose
    evaluation; its Evaluation, None when none could be made)."""
    from handeye_ros.evaluation.outputs import evaluation_of, judge_figures

    found = evaluation_of(res)
    return (res, None) if found is None else (judge_figures(res, found[0]), found[0])


def truth_within(res, ev, dt_s: float, q_HE: np.ndarray, p_HE: np.ndarray) -> list[float | None]:
    """For each of APE_KEYS, |its rmse at the calibration (dt_s, q_HE, p_HE) - the reported one|
    over its calibration 1-sigma (``ev``: the result's Evaluation); None without error bars."""
    from handeye_ros.evaluation.error_bars import figures_at

    if ev is None or ev.sigmas is None or res.batch is None:
        return [None] * len(APE_KEYS)
    moved = figures_at(res, dt_s, q_HE, p_HE)
    sigmas = [ev.sigmas.sigmas[key]['rmse'] for key in APE_KEYS]
    return [
        None if moved is None or not sigma else abs(moved[key]['rmse']) / sigma
        for key, sigma in zip(APE_KEYS, sigmas, strict=True)
    ]
