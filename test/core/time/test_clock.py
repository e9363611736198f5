"""Clock drift (core/time/clock.py, core/stages/drift.py): the line fits, the pipeline with and
without clock_drift, bad input; and the drift and scale options end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import recording, run_main

from handeye_ros.core.checks.verdict import drift_significant, drift_threshold_sigmas
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import ConfigError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import calibration_error
from handeye_ros.core.time.clock import (
    DriftFit,
    fit_drift,
    least_squares_line,
    repeated_medians_line,
    retime,
)
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats import write_tum


def test_fit_drift_recovers_a_line_and_ignores_a_wrong_window() -> None:
    """Windows on an exact line with one window locked onto a wrong peak (+0.4 s): the line is
    the true one and the wrong window is not used."""
    centres = np.arange(12, dtype=np.int64) * 30_000_000_000
    offsets = 0.05 + 200e-6 * (centres - centres[6]) * 1e-9
    offsets[3] += 0.4
    fit = fit_drift(centres, offsets, np.full(12, 0.9), int(centres[6]), 330.0)
    assert fit.drift == pytest.approx(200e-6, abs=1e-9)
    assert not fit.inliers[3] and fit.inliers.sum() == 11
    assert float(fit.offset_at(centres[6])) == pytest.approx(0.05, abs=1e-9)
    assert drift_significant(fit)  # 66 ms over the recording


@pytest.mark.slow
def test_line_fits_match_scipy_stats() -> None:
    """The two line fits written out in core/time/clock.py (to spare every run scipy.stats' 1.3 s
    import) give scipy's numbers, wild points included."""
    from scipy import stats

    rng = np.random.default_rng(4)
    for n in (4, 7, 16):
        x = np.sort(rng.uniform(-300, 300, n))
        y = 2e-3 + 5e-5 * x + rng.normal(scale=5e-4, size=n)
        y[n // 3] += 0.05  # a window on a wrong peak
        ref = stats.siegelslopes(y, x)
        np.testing.assert_allclose(
            repeated_medians_line(x, y), (ref.slope, ref.intercept), rtol=1e-12, atol=1e-15
        )
        lr = stats.linregress(x, y)
        np.testing.assert_allclose(
            least_squares_line(x, y), (lr.slope, lr.intercept, lr.stderr), rtol=1e-10
        )


@pytest.mark.slow
def test_drift_significance_uses_the_t_quantile_of_its_windows() -> None:
    """A drift's sigma comes from a few windows' scatter: the bar is Student's t at the false
    alarm rate of 3 Gaussian sigmas, higher the fewer the windows."""
    from scipy import stats

    def fit(n: int, drift: float) -> DriftFit:
        return DriftFit(
            drift,
            1e-6,
            0.0,
            1e-4,
            0,
            6000.0,
            np.zeros(n, np.int64),
            np.zeros(n),
            np.ones(n),
            np.ones(n, bool),
        )

    for n in (4, 6, 15):
        bar = stats.t.ppf(stats.norm.cdf(3.0), n - 2)
        assert drift_threshold_sigmas(fit(n, 1e-6)) == pytest.approx(bar)
        assert drift_significant(fit(n, 1.01 * bar * 1e-6))
        assert not drift_significant(fit(n, 0.99 * bar * 1e-6))
    assert drift_threshold_sigmas(fit(15, 3.6e-6)) > 3.6  # the false alarm of a 10-min simulation


def test_fit_drift_refuses_too_few_windows() -> None:
    centres = np.arange(3, dtype=np.int64) * 10_000_000_000
    fit = fit_drift(centres, np.zeros(3), np.ones(3), 0, 30.0)
    assert not fit.estimated and 'too short' in fit.why


def test_retime_composes_and_keeps_the_reference_stamp() -> None:
    """Two drifts about one stamp are one drift d1 + d2 (1 - d1), to the nanosecond."""
    t = np.arange(0, 600_000_000_000, 33_000_000, dtype=np.int64) + 1_700_000_000_000_000_000
    traj = Trajectory.from_arrays(t, np.zeros((t.size, 3)), np.tile([0, 0, 0, 1.0], (t.size, 1)))
    ref = int(t[t.size // 2])
    d1, d2 = 300e-6, -120e-6
    twice = retime(retime(traj, d1, ref), d2, ref)
    once = retime(traj, d1 + d2 * (1 - d1), ref)
    assert np.max(np.abs(twice.t_ns - once.t_ns)) <= 2
    assert twice.t_ns[t.size // 2] == ref


@pytest.mark.slow
def test_clock_drift_is_estimated_in_all_stages() -> None:
    """300 ppm over 3 minutes (54 ms end to end), noise level 3: with clock_drift, the drift
    within 5 ppm (the windows alone resolve ~3 ppm here, the batch stage better) and dt at the
    first and the last eye pose within 2 ms (the issue's figures); T_HE as without drift."""
    rec = recording(seed=3, level=3.0, duration_s=180.0, clock_drift=300e-6)
    res = calibrate(rec.hand, rec.eye, CalibrationConfig(clock_drift=True))
    assert res.batch is not None and res.batch.clock_drift is not None
    assert abs(res.clock_drift - 300e-6) < 5e-6
    ends = rec.eye.t_ns[[0, -1]]
    assert np.max(np.abs(res.time_offset_at(ends) - rec.truth.time_offset_at(ends))) < 2e-3
    e = calibration_error(rec.truth, rec.truth.time_offset_s, res.q_HE, res.p_HE)
    assert e.translation_m < 0.01 and e.rotation_deg < 0.3
    d = res.to_dict()
    assert d['clock_drift'] == pytest.approx(res.clock_drift)
    assert d['time_offset_stamp_ns'] == res.eye_model.time_offset_stamp_ns
    assert d['std']['clock_drift'] > 0 and 'clock_drift' in d['covariance']['order']
    # the result holds at its own reference stamp
    assert (
        abs(res.time_offset_s - float(rec.truth.time_offset_at(d['time_offset_stamp_ns']))) < 1e-3
    )


@pytest.mark.slow
def test_default_run_fits_a_drift_it_measures_and_says_so() -> None:
    rec = recording(seed=3, level=3.0, duration_s=180.0, clock_drift=300e-6)
    res = calibrate(rec.hand, rec.eye)
    assert res.clock_drift == pytest.approx(300e-6, abs=5e-6)
    assert 'clock_drift' not in res.quality.codes
    note = res.quality.notes[0]
    assert note.startswith(f'clock drift {res.clock_drift * 1e6:+.1f} ppm measured (')
    assert note.endswith(
        'and fitted; --no-clock-drift (auto_drift false) keeps one constant offset'
    )
    d = res.to_dict()
    assert (
        abs(res.time_offset_s - float(rec.truth.time_offset_at(d['time_offset_stamp_ns']))) < 1e-3
    )


@pytest.mark.slow
def test_without_auto_drift_a_drift_is_named_with_its_rate() -> None:
    rec = recording(seed=3, level=3.0, duration_s=180.0, clock_drift=300e-6)
    res = calibrate(rec.hand, rec.eye, CalibrationConfig(auto_drift=False))
    assert res.clock_drift is None
    assert 'clock_drift' in res.quality.codes
    text = next(r.message for r in res.quality.reasons if r.code == 'clock_drift')
    rate = float(text.split(' at ')[1].split(' ')[0])
    assert rate == pytest.approx(300, abs=15)  # ppm, from windows only
    assert '--clock-drift' in text
    assert res.to_dict()['clock']['drift_significant']


@pytest.mark.slow
def test_no_drift_is_not_named_and_the_option_costs_little() -> None:
    rec = recording(seed=5, level=3.0, duration_s=120.0)
    plain = calibrate(rec.hand, rec.eye)
    assert 'clock_drift' not in plain.quality.codes
    assert any('constant within its uncertainty' in n for n in plain.quality.notes)
    drift = calibrate(rec.hand, rec.eye, CalibrationConfig(clock_drift=True))
    assert abs(drift.clock_drift) < 3 * drift.eye_model.drift_std + 1e-6
    e0 = calibration_error(rec.truth, plain.time_offset_s, plain.q_HE, plain.p_HE)
    e1 = calibration_error(rec.truth, drift.time_offset_s, drift.q_HE, drift.p_HE)
    assert e1.translation_m < e0.translation_m + 2e-3
    assert e1.rotation_deg < e0.rotation_deg + 0.05


def test_drift_on_a_short_recording_is_called_unobservable() -> None:
    rec = recording(seed=1, level=2.0, duration_s=32.0)
    res = calibrate(rec.hand, rec.eye, CalibrationConfig(clock_drift=True))
    assert res.clock_drift is None and res.to_dict()['clock_drift'] is None
    reason = next(r.message for r in res.quality.reasons if r.code == 'unobservable')
    assert 'clock drift cannot be observed' in reason and 'too short' in reason


def test_drift_with_a_tiny_overlap_is_called_unobservable() -> None:
    """Two minutes of hand, but only 25 s of it seen by the eye."""
    rec = recording(seed=1, level=2.0, duration_s=120.0)
    eye = rec.eye.select(slice(0, 25 * 20))
    res = calibrate(rec.hand, eye, CalibrationConfig(clock_drift=True))
    assert res.clock_drift is None and 'unobservable' in res.quality.codes


def test_drift_with_a_fixed_offset_is_refused() -> None:
    with pytest.raises(ConfigError, match='give one of them'):
        rec = recording(seed=1)
        calibrate(rec.hand, rec.eye, CalibrationConfig(clock_drift=True, time_offset=0.0))


@pytest.mark.slow
def test_cli_flags_and_result_keys(tmp_path) -> None:
    rec = recording(seed=2, level=2.0, duration_s=60.0, scale=2.0)
    write_tum(tmp_path / 'h.txt', rec.hand)
    write_tum(tmp_path / 'e.txt', rec.eye)
    out = run_main(
        '--hand',
        tmp_path / 'h.txt',
        '--eye',
        tmp_path / 'e.txt',
        '--scale',
        '--clock-drift',
        '--json',
    )
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    assert d['scale'] == pytest.approx(2.0, rel=0.01)
    assert 'clock_drift' in d and 'time_offset_stamp' in d
    assert d['config']['estimate_scale'] and d['config']['clock_drift']


def test_world_metrics_survive_a_one_pose_segment() -> None:
    """A drifting eye split at a break one pose before its end (seen on a real pair with 1000
    ppm put in): the metrics of that one-pair segment are computed, not a LinAlgError."""
    from handeye_ros.core.association import associate
    from handeye_ros.core.world import align_worlds, metrics_of

    rec = recording(seed=1, level=1.0, duration_s=20.0)
    eye = rec.eye.with_breaks(np.array([len(rec.eye) - 2]))
    pairs = associate(rec.hand, eye, rec.truth.time_offset_s)
    assert np.sum(pairs.segment == pairs.segment.max()) == 1
    m = metrics_of(
        pairs, rec.truth.q_HE, rec.truth.p_HE, align_worlds(pairs, rec.truth.q_HE, rec.truth.p_HE)
    )
    assert np.isfinite(m.ape_rmse_m)
