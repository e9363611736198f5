"""Fuzzing: no input and no option value ends in anything but a result or a HandeyeError.

The offline tool and the node turn a HandeyeError into one line for the user; any other
exception would be a traceback. hypothesis generates the inputs (files of arbitrary text and
bytes, option mappings of arbitrary values, small trajectories of arbitrary poses and stamps)
and shrinks any failure to a minimal case.
"""

from __future__ import annotations

import functools
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import recording
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handeye_ros.app.offline import main as offline_main
from handeye_ros.core.checks.verdict import Quality
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats import read_trajectory, write_tum

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@functools.cache
def _short_files() -> tuple[Path, Path]:
    """A 15 s recording as TUM files, written once per session."""
    rec = recording(seed=11, level=2.0, duration_s=15.0)
    out = Path(tempfile.mkdtemp(prefix='fuzz-'))
    write_tum(out / 'hand.txt', rec.hand)
    write_tum(out / 'eye.txt', rec.eye)
    return out / 'hand.txt', out / 'eye.txt'


number = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**25), max_value=10**25),
    st.sampled_from(['1e300', '-0', '1.403636579758555555e9', '0x10', 'nan', '', '1.2.3']),
)


def _row(values: list, sep: str) -> str:
    return sep.join(str(v) for v in values)


@st.composite
def text_files(draw) -> str:
    sep = draw(st.sampled_from([' ', ',', '\t', ', ']))
    rows = draw(st.lists(st.lists(number, min_size=0, max_size=19), min_size=0, max_size=12))
    lines = [_row(r, sep) for r in rows]
    if draw(st.booleans()):
        lines.insert(0, '# t x y z qx qy qz qw')
    return '\n'.join(lines) + draw(st.sampled_from(['', '\n', '\r\n']))


@SETTINGS
@given(
    content=text_files(),
    fmt=st.sampled_from(['auto', 'tum', 'euroc']),
    unit=st.sampled_from(['auto', 's', 'ms', 'us', 'ns']),
    order=st.sampled_from(['auto', 'xyzw', 'wxyz']),
)
def test_reader_on_arbitrary_text(content: str, fmt: str, unit: str, order: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'traj.txt'
        path.write_text(content)
        try:
            traj = read_trajectory(path, fmt, unit, order)
        except HandeyeError:
            return
        assert np.all(np.diff(traj.t_ns) > 0) and np.isfinite(traj.p_xyz).all()
        np.testing.assert_allclose(np.linalg.norm(traj.q_xyzw, axis=1), 1.0, atol=1e-9)


@SETTINGS
@given(data=st.binary(max_size=400))
def test_reader_on_arbitrary_bytes(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'traj.csv'
        path.write_bytes(data)
        try:
            traj = read_trajectory(path)
        except HandeyeError:
            return
        # what it reads is a valid stream
        assert np.all(np.diff(traj.t_ns) > 0) and np.isfinite(traj.p_xyz).all()
        np.testing.assert_allclose(np.linalg.norm(traj.q_xyzw, axis=1), 1.0, atol=1e-9)


option_value = st.one_of(
    st.none(), st.booleans(), number, st.text(max_size=12), st.lists(st.integers(), max_size=2)
)


@pytest.mark.slow
@SETTINGS
@given(
    values=st.dictionaries(
        st.sampled_from(list(CalibrationConfig.specs()) + ['typo']), option_value, max_size=6
    )
)
def test_options_on_arbitrary_values(values: dict) -> None:
    try:
        cfg = CalibrationConfig.from_mapping(values)
    except HandeyeError:
        return
    for name, spec in cfg.specs().items():
        v = getattr(cfg, name)
        if spec.kind in ('float', 'int') and v is not None:
            assert math.isfinite(v)


@st.composite
def trajectories(draw, name: str) -> Trajectory:
    n = draw(st.integers(min_value=2, max_value=60))
    steps = draw(
        st.lists(st.integers(min_value=1, max_value=10**9), min_size=n - 1, max_size=n - 1)
    )
    t0 = draw(st.integers(min_value=0, max_value=2 * 10**18))
    t = t0 + np.concatenate(([0], np.cumsum(steps)))
    if t[-1] > 9 * 10**18:
        t = t - t[0]
    p = np.array(
        draw(
            st.lists(
                st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3), min_size=n, max_size=n
            )
        )
    )
    q = np.array(
        draw(st.lists(st.lists(st.floats(-1, 1), min_size=4, max_size=4), min_size=n, max_size=n))
    )
    norms = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norms > 1e-3, q / np.where(norms > 0, norms, 1.0), [0.0, 0.0, 0.0, 1.0])
    return Trajectory.from_arrays(t.astype(np.int64), p, q, name)


@pytest.mark.slow
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(hand=trajectories('hand'), eye=trajectories('eye'))
def test_calibrate_on_arbitrary_trajectories(hand: Trajectory, eye: Trajectory) -> None:
    try:
        res = calibrate(hand, eye)
    except HandeyeError:
        return
    # a result, when there is one, is coherent: finite numbers, a unit quaternion, the verdict
    # of its worst reason, and a dictionary the writers can write
    assert np.isfinite(res.time_offset_s) and np.isfinite(res.p_HE).all()
    assert abs(np.linalg.norm(res.q_HE) - 1.0) < 1e-9
    worst = Quality.from_reasons(list(res.quality.reasons), []).verdict
    assert res.quality.verdict == worst
    yaml.safe_dump(res.to_dict())


@pytest.mark.slow
@settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    option=st.sampled_from(
        [
            '--time-offset',
            '--time-offset-guess',
            '--max-time-offset',
            '--resample-rate-hz',
            '--eta',
            '--mu',
            '--ransac-iterations',
            '--inlier-rotation',
            '--knot-spacing',
            '--huber-delta',
            '--outlier-threshold',
            '--max-outlier-fraction',
            '--batch-max-iterations',
            '--min-motions',
            '--seed',
        ]
    ),
    value=st.sampled_from(
        [
            '0',
            '-1',
            '1e18',
            '1403636579758555555',
            'nan',
            'inf',
            '-inf',
            '1e-300',
            '100000',
            '0.0001',
            '3',
            'x',
        ]
    ),
)
def test_offline_tool_on_absurd_option_values(option: str, value: str, capsys) -> None:
    """Exit codes 0 (a result), 1 (a one-line error), 2 (argparse's usage error); never an
    exception, a MemoryError or an internal error (3)."""
    hand, eye = _short_files()
    try:
        code = offline_main(['--hand', str(hand), '--eye', str(eye), '--json', option, value])
    except SystemExit as exc:  # argparse: a value of the wrong type
        code = exc.code
    err = capsys.readouterr().err
    assert code in (0, 1, 2), err
    assert 'internal error' not in err and 'Traceback' not in err


stamp_token = st.one_of(
    st.integers(min_value=-(10**19), max_value=10**19).map(str),
    st.decimals(
        min_value=-(10**12), max_value=10**12, allow_nan=False, allow_infinity=False, places=12
    ).map(lambda d: format(d, 'f')),
    st.sampled_from(
        [
            '+1.5',
            '-0.000000001',
            '.5',
            '5.',
            '00012.3400',
            '1.4e9',
            '1..2',
            '-',
            '٣.5',
            '1403636579.758555555123',
        ]
    ),
)


@SETTINGS
@given(
    stamps=st.lists(stamp_token, min_size=1, max_size=30),
    sep=st.sampled_from([' ', '\t', ',']),
    comment=st.booleans(),
)
def test_bulk_reader_agrees_with_the_line_by_line_one(
    stamps: list[str], sep: str, comment: bool
) -> None:
    """What formats/bulk.py reads from the bytes, it reads as the line-by-line reader does."""
    from handeye_ros.formats import bulk, text

    fmt = 'euroc' if sep == ',' else 'tum'
    lines = ['# header'] if comment else []
    lines += [sep.join([s, '0.5', '1', '2', '0', '0', '0', '1']) for s in stamps]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'traj.txt'
        path.write_text('\n'.join(lines) + '\n', encoding='utf-8')
        data = path.read_bytes()
        fast = bulk.read_bulk(path, data, lambda n, row: (fmt, ',' if fmt == 'euroc' else None))
        try:
            numbers, values, split, _ = text._read_lines(path, data, fmt)
        except HandeyeError:
            assert fast is None
            return
    if fast is None:
        return
    table = fast[1]
    np.testing.assert_array_equal(table.numbers, numbers)
    np.testing.assert_array_equal(table.values, values)
    for name in ('whole', 'frac9', 'fractional', 'neg'):
        np.testing.assert_array_equal(
            getattr(table.stamps, name), getattr(split, name), err_msg=name
        )
