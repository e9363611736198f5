"""The report's figures, one function per PNG (matplotlib's object API with the Agg canvas: no
pyplot state, no display, safe in worker processes).

Every function takes what it draws and a path, writes one PNG and returns its caption. Long
streams are thinned to at most :data:`.figures.MAX_POINTS` points per line: an hour at 1 kHz is 3.6 M
samples, far more than a plot shows.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.arrays import Floats
from ..core.document import Row
from ..core.result import CalibrationResult
from ..core.time.signals import angular_speed, spans
from .aligned import AlignedTrajectories
from .figures import DPI, canvas, save, say_empty, thinned

#: Lags of the residual autocorrelation plot.
MAX_LAGS = 60
HAND, EYE, REF = '#1f77b4', '#d62728', '#2ca02c'


def time_alignment(result: CalibrationResult, path: Path) -> str:
    """Angular speed of both streams before and after the alignment, and the correlation."""
    used, ta = result.streams(), result.time_alignment
    n_h, n_e = spans(used.hand, used.eye)
    w_h, w_e = angular_speed(used.hand, span=n_h), angular_speed(used.eye, span=n_e)
    fig, ax = canvas(3)
    sh, se = thinned(w_h.t_s.size), thinned(w_e.t_s.size)
    ax[0, 0].plot(w_h.t_s[sh], np.degrees(w_h.speed[sh]), color=HAND, lw=0.7, label='hand')
    ax[0, 0].plot(w_e.t_s[se], np.degrees(w_e.speed[se]), color=EYE, lw=0.7, label='eye')
    ax[0, 0].set_title('before: each stream from its own first stamp')
    # after: the eye at hand time t_eye - dt; both from the hand's first stamp
    hand0 = int(used.hand.t_ns[0])
    t_after = (used.eye.t_ns[0] - hand0) * 1e-9 - used.time_offset_s + w_e.t_s
    ax[1, 0].plot(w_h.t_s[sh], np.degrees(w_h.speed[sh]), color=HAND, lw=0.7, label='hand')
    ax[1, 0].plot(
        t_after[se],
        np.degrees(w_e.speed[se]),
        color=EYE,
        lw=0.7,
        alpha=0.8,
        label=f'eye, moved by dt = {result.time_offset_s * 1e3:+.2f} ms',
    )
    ax[1, 0].set_title('after: the eye on the hand clock')
    for a in ax[:2, 0]:
        a.set_xlabel('time [s]')
        a.set_ylabel('angular speed [deg/s]')
        a.legend(loc='upper right', fontsize='small')
    c = ax[2, 0]
    if ta.lags_s is not None and ta.correlation is not None and ta.correlation.size:
        s = thinned(ta.lags_s.size)
        c.plot(ta.lags_s[s], ta.correlation[s], color='k', lw=0.8)
        c.axvline(
            ta.time_offset_s,
            color=EYE,
            lw=1.0,
            label=f'chosen {ta.time_offset_s:+.4f} s (r = {ta.peak_correlation:.3f})',
        )
        others = [(o, r) for o, r in ta.candidates if abs(o - ta.time_offset_s) > 1e-9]
        if others:
            o, r = others[0]
            c.axvline(o, color='0.5', ls='--', lw=1.0, label=f'runner-up {o:+.4f} s (r = {r:.3f})')
        c.legend(loc='upper right', fontsize='small')
        c.set_title(f'normalised cross-correlation of the angular speeds ({ta.method} peak)')
    else:
        say_empty(c, f'no correlation curve: the offset was {ta.method}')
    c.set_xlabel('time offset dt = eye clock - hand clock [s]')
    c.set_ylabel('correlation')
    save(fig, path)
    return (
        'Stage 1: the angular speed of both streams before and after the alignment, and '
        'the correlation over the searched offsets with the chosen and the runner-up peak.'
    )


def clock(result: CalibrationResult, path: Path) -> str:
    """The offset measured in windows along the recording (the drift check)."""
    fit = result.clock
    fig, ax = canvas(1, height=3.4)
    a = ax[0, 0]
    if fit is None or fit.centres_ns.size == 0:
        say_empty(a, 'no windows: the recording is too short or the offset was fixed')
    else:
        t0 = int(fit.centres_ns[0])
        t = (fit.centres_ns - t0) * 1e-9
        used = fit.inliers.astype(bool)
        a.plot(t[used], fit.offsets_s[used] * 1e3, 'o', color=HAND, label='window (used)')
        if (~used).any():
            a.plot(
                t[~used], fit.offsets_s[~used] * 1e3, 'x', color='0.5', label='window (not used)'
            )
        tt = np.linspace(t.min(), t.max(), 50)
        stamps = t0 + np.rint(tt * 1e9).astype(np.int64)
        a.plot(
            tt,
            result.time_offset_at(stamps) * 1e3,
            color=EYE,
            label='result'
            + (
                f' (drift {result.clock_drift * 1e6:+.2f} ppm)'
                if result.clock_drift is not None
                else ' (one offset)'
            ),
        )
        if np.isfinite(fit.drift):
            a.plot(
                tt,
                (fit.offset_s + fit.drift * ((stamps - fit.stamp_ns) * 1e-9)) * 1e3,
                color='k',
                ls=':',
                label=f'line through the windows ({fit.drift * 1e6:+.2f} '
                f'+- {fit.drift_std * 1e6:.2f} ppm)',
            )
        a.legend(fontsize='small')
    a.set_xlabel('eye time [s]')
    a.set_ylabel('time offset [ms]')
    a.set_title('time offset measured in windows along the recording')
    save(fig, path)
    return (
        'The offset measured in windows along the recording: a slope is a clock drift; '
        'the line the result uses is drawn through them.'
    )


def linear(result: CalibrationResult, path: Path) -> str:
    """Stage 2: the motions' residuals (inliers and outliers) and their rotation axes."""
    lin = result.linear
    m = lin.motions
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4.2), dpi=DPI, layout='constrained')
    a = fig.add_subplot(1, 2, 1)
    b = fig.add_subplot(1, 2, 2, projection='3d')
    if m is None or len(m) == 0:
        say_empty(a, 'no motions')
    else:
        from ..core.linear.axxb import motion_errors

        e_rot, e_trans = motion_errors(m, lin.q_HE[None], lin.p_HE[None])
        inl = lin.inliers.astype(bool)
        a.loglog(
            np.degrees(e_rot[0, inl]),
            e_trans[0, inl] * 1e3,
            '.',
            color=HAND,
            ms=4,
            label=f'inliers ({inl.sum()})',
        )
        if (~inl).any():
            a.loglog(
                np.degrees(e_rot[0, ~inl]),
                e_trans[0, ~inl] * 1e3,
                '.',
                color=EYE,
                ms=4,
                label=f'outliers ({(~inl).sum()})',
            )
        a.axvline(lin.inlier_rotation_deg, color='0.4', ls='--', lw=0.8)
        a.axhline(
            lin.inlier_translation_m * 1e3, color='0.4', ls='--', lw=0.8, label='inlier thresholds'
        )
        a.legend(fontsize='small')
        # rotation axes of the hand motions (sign-free: the upper hemisphere of z)
        rv = _axes(m.qa)
        sel = inl if inl.any() else np.ones(rv.shape[0], bool)
        b.scatter(*rv[sel].T, s=6, color=HAND)
        if (~sel).any():
            b.scatter(*rv[~sel].T, s=6, color=EYE)
        u, v = np.mgrid[0 : 2 * np.pi : 24j, 0 : np.pi : 12j]
        b.plot_wireframe(
            np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color='0.85', lw=0.4
        )
        b.set_box_aspect((1, 1, 1))
    a.set_xlabel('rotation error of X B X^-1 A^-1 [deg]')
    a.set_ylabel('translation error [mm]')
    a.set_title(f'linear stage: {lin.n_inliers}/{lin.n_motions} inlier motions')
    b.set_title(f'rotation axes of the motions (spread {lin.axis_spread_deg:.0f} deg)')
    save(fig, path)
    return (
        'Stage 2: the error of every keyframe motion at the linear solution (inliers '
        "blue, outliers red, dashed: the inlier thresholds), and the motions' rotation "
        'axes on the unit sphere: axes spread over the sphere make T_HE observable.'
    )


def excitation(result: CalibrationResult, path: Path) -> str:
    """How far the device (the eye) has turned about each of its axes, over the recording."""
    fig, ax = canvas(1, height=3.2)
    a = ax[0, 0]
    used = result.used
    if used is None or len(used.eye) < 3:
        say_empty(a, 'no eye poses')
    else:
        from ..core.geometry import consecutive_rotvecs

        eye = used.eye
        ok = eye.interval_ok()
        turned = np.degrees(np.cumsum(np.abs(consecutive_rotvecs(eye.q_xyzw)) * ok[:, None], 0))
        t = eye.seconds(int(eye.t_ns[0]))[1:]
        k = thinned(t.size)
        for col, (axis, color) in enumerate(zip('xyz', ('tab:red', 'tab:green', 'tab:blue'))):
            a.plot(t[k], turned[k, col], color=color, label=f'about its {axis} axis')
        a.legend(fontsize='small')
    a.set_title('rotation of the device about its axes')
    a.set_xlabel('eye time [s]')
    a.set_ylabel('turned so far [deg]')
    save(fig, path)
    return (
        'How far the device has turned about each of its own axes since the start: the '
        'steep parts of a curve are the parts of the recording that carry T_HE about that '
        'axis; a flat curve is an axis the motion never excited.'
    )


def _axes(q: Floats) -> Floats:
    v = np.asarray(q)[:, :3]
    n = np.linalg.norm(v, axis=1, keepdims=True)
    v = np.divide(v, n, out=np.zeros_like(v), where=n > 0)
    return v * np.where(v[:, 2:3] < 0, -1.0, 1.0)


def step_residuals(result: CalibrationResult) -> tuple[Floats, Floats, Floats]:
    """Relative-pose residuals of consecutive eye poses against the calibrated hand
    (eq. 16's, with the hand interpolated rather than splined): times (s, eye), rotation
    residual vectors (rad, (M, 3)) and translation residuals (m, (M, 3)), in the eye frame."""
    from scipy.spatial.transform import Rotation

    from ..core.association import eye_motion_residuals
    from ..core.geometry import matrix_from_quat

    used = result.streams()
    eye = used.eye
    k = np.flatnonzero(eye.interval_ok())
    R_err, p_err, covered = eye_motion_residuals(
        used.hand, eye, k, k + 1, used.time_offset_s, (matrix_from_quat(result.q_HE), result.p_HE)
    )
    t = eye.seconds(int(eye.t_ns[0]))[k[covered]]
    return t, Rotation.from_matrix(R_err[covered]).as_rotvec(), p_err[covered]


def residuals(result: CalibrationResult, path: Path) -> str:
    """Residuals over time and their autocorrelation."""
    t, r, p = step_residuals(result)
    fig, ax = canvas(3, height=2.6)
    s = thinned(t.size)
    for k, name in enumerate('xyz'):
        ax[0, 0].plot(t[s], np.degrees(r[s, k]), lw=0.6, label=name)
        ax[1, 0].plot(t[s], p[s, k] * 1e3, lw=0.6, label=name)
    ax[0, 0].set_ylabel('rotation [deg]')
    ax[1, 0].set_ylabel('translation [mm]')
    for a in ax[:2, 0]:
        a.set_xlabel('eye time [s]')
        a.legend(loc='upper right', fontsize='small', ncol=3)
    ax[0, 0].set_title('residuals of consecutive eye motions against the calibrated hand')
    c = ax[2, 0]
    lags = np.arange(MAX_LAGS + 1)
    for k, name in enumerate('xyz'):
        c.plot(lags, _acf(p[:, k], MAX_LAGS), '.-', lw=0.7, label=f'translation {name}')
    c.plot(lags, _acf(np.linalg.norm(r, axis=1), MAX_LAGS), 'k.-', lw=0.7, label='rotation angle')
    if t.size > 1:
        c.axhspan(-2 / np.sqrt(t.size), 2 / np.sqrt(t.size), color='0.9', label='white-noise band')
    c.set_xlabel('lag [eye poses]')
    c.set_ylabel('autocorrelation')
    c.legend(loc='upper right', fontsize='small', ncol=2)
    save(fig, path)
    bw = result.batch.bandwidth if result.batch is not None else None
    return (
        'Residuals of every consecutive eye motion against the calibrated hand motion '
        '(T_HE^-1 A T_HE vs B, eq. 16 with the hand interpolated), and their '
        'autocorrelation: correlated residuals (VIO drift) are why the uncertainty uses a '
        'long-run covariance' + (f' (bandwidth {bw} eye poses).' if bw is not None else '.')
    )


def _acf(x: Floats, lags: int) -> Floats:
    x = np.asarray(x, dtype=float) - np.mean(x) if np.size(x) else np.zeros(1)
    d = float(np.dot(x, x))
    out = np.full(lags + 1, np.nan)
    if d <= 0:
        return out
    for k in range(min(lags, x.size - 1) + 1):
        out[k] = float(np.dot(x[: x.size - k], x[k:])) / d
    return out


def trajectories(
    al: AlignedTrajectories,
    path: Path,
    ape_t: Floats,
    base: AlignedTrajectories | None = None,
    base_ape_t: Floats | None = None,
) -> str:
    """Top view, x/y/z over time and APE over time of the eye and the calibrated ground truth."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 10), dpi=DPI, layout='constrained')
    grid = fig.add_gridspec(4, 2)
    top = fig.add_subplot(grid[:3, 0])
    xyz = [fig.add_subplot(grid[k, 1]) for k in range(3)]
    err = fig.add_subplot(grid[3, :])
    t = al.seconds()
    s = thinned(t.size)
    top.plot(al.p_ref[s, 0], al.p_ref[s, 1], color=REF, lw=0.8, label='ground truth (calibrated)')
    top.plot(al.p_est[s, 0], al.p_est[s, 1], color=EYE, lw=0.8, label='eye')
    top.set_aspect('equal', adjustable='datalim')
    top.set_xlabel('x [m] (eye world)')
    top.set_ylabel('y [m]')
    top.set_title('top view')
    top.legend(fontsize='small')
    for k, a in enumerate(xyz):
        a.plot(t[s], al.p_ref[s, k], color=REF, lw=0.8)
        a.plot(t[s], al.p_est[s, k], color=EYE, lw=0.8)
        a.set_ylabel(f'{"xyz"[k]} [m]')
    xyz[-1].set_xlabel('eye time [s]')
    err.plot(
        t[s],
        ape_t[s] * 1e3,
        color='k',
        lw=0.8,
        label=f'with the calibration (RMSE {np.sqrt(np.mean(ape_t**2)) * 1e3:.1f} mm)',
    )
    if base is not None and base_ape_t is not None:
        tb = (base.t_ns - al.t_ns[0]) * 1e-9
        sb = thinned(tb.size)
        err.plot(
            tb[sb],
            base_ape_t[sb] * 1e3,
            color='0.6',
            lw=0.8,
            label=f'without (dt = 0, no T_HE, SE(3) fit; RMSE '
            f'{np.sqrt(np.mean(base_ape_t**2)) * 1e3:.1f} mm)',
        )
    err.set_xlabel('eye time [s]')
    err.set_ylabel('APE [mm]')
    err.set_title('absolute position error over time')
    err.legend(fontsize='small')
    save(fig, path)
    return (
        "The eye and the MoCap ground truth mapped into the eye's world and clock "
        '(T_WG T_GH(t - dt) T_HE): top view, x/y/z over time, and the position error over '
        'time with and without the calibration.'
    )


def summary(rows: list[Row], path: Path) -> str:
    """Box plots of the successful runs' APE and RPE per algorithm and per sequence."""
    ok = [r for r in rows if r.get('status') == 'ok' and r.get('ape_mm') is not None]
    metrics = (
        ('ape_mm', 'APE [mm], calibrated'),
        ('rpe_1s_mm', 'RPE per 1 s [mm]'),
        ('ape_uncalibrated_mm', 'APE [mm], dt = 0, no T_HE, SE(3) fit'),
    )
    fig, ax = canvas(len(metrics), 2, height=2.8, width=11.0)
    for row, (key, label) in enumerate(metrics):
        for col, group in enumerate(('algorithm', 'sequence')):
            a = ax[row, col]
            names = sorted({str(r.get(group) or '-') for r in ok})
            data = [
                [r[key] for r in ok if str(r.get(group) or '-') == n and r.get(key) is not None]
                for n in names
            ]
            shown = [(n, d) for n, d in zip(names, data, strict=True) if d]
            if shown:
                a.boxplot([d for _, d in shown])
                # the labels apart: boxplot's keyword is labels before matplotlib 3.9 (Jazzy's
                # 3.6) and tick_labels after
                a.set_xticks(range(1, len(shown) + 1), [n for n, _ in shown])
                a.tick_params(axis='x', labelrotation=30)
            else:
                say_empty(a, 'no successful runs')
            a.set_ylabel(label, fontsize='small')
            a.set_title(f'per {group} ({len(ok)} of {len(rows)} runs)', fontsize='small')
    save(fig, path)
    return 'APE and RPE of the successful runs per algorithm and per sequence.'
