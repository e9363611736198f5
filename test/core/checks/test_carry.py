"""READY with a result's own factors and reasons (core/checks/carry.py): the predictions times
the last result's reported over predicted sigmas, READY held back while a result is not
``good``, and a result's own ``readiness`` never READY beside a doubtful verdict."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import recording

from handeye_ros.core.checks.carry import (
    LACKS_BLOCKS,
    carry_over,
    held_reasons,
    predictor_factors,
)
from handeye_ros.core.checks.verdict import BLOCKS_MARGIN
from handeye_ros.core.pipeline import calibrate
from handeye_ros.evaluation.terminal import readiness_lines

SIGMA = {'time_offset_ms': 0.4, 'translation_mm': 6.0, 'rotation_deg': 0.2}
TARGET = {'time_offset_ms': 1.0, 'translation_mm': 10.0, 'rotation_deg': 0.5}


def _ready(sigma: dict[str, float]) -> dict:
    """A READY status of the node, its predictions not yet carried."""
    return {'ready': True, 'sigma': sigma, 'predicted': sigma, 'target': TARGET, 'missing': []}


def test_the_predictions_carry_the_last_calibrations_own_sigmas() -> None:
    """The readiness predicts sigmas from consecutive pairs; the last calibration's reported
    sigmas were 1.2 and 2 times what its own readiness predicted on the same data: the
    predictions are too, and READY waits for them."""
    last = _ready(SIGMA)
    assert carry_over(last, {}, []) == last
    document = {
        'std': {
            'time_offset': 0.48e-3,
            'translation': [12e-3 / np.sqrt(3)] * 3,
            'rotation': [np.radians(0.2) / np.sqrt(3)] * 3,
        },
        'readiness': {**_ready(SIGMA), 'sigma': {k: 2 * v for k, v in SIGMA.items()}},
    }
    factors = predictor_factors(document)  # of the predictions, whatever was carried
    assert factors == pytest.approx(
        {'time_offset_ms': 1.2, 'translation_mm': 2.0, 'rotation_deg': 1.0}
    )
    wider = carry_over(last, factors, [])
    assert wider['sigma']['translation_mm'] == pytest.approx(12.0)
    assert wider['sigma']['time_offset_ms'] == pytest.approx(0.48)
    assert wider['predicted'] == SIGMA
    assert not wider['ready'] and wider['missing'][0].startswith('keep recording')
    assert last['ready'] and last['sigma']['translation_mm'] == 6.0  # not changed in place
    narrower = carry_over(last, {'translation_mm': 0.5}, [])
    assert narrower['ready'] and narrower['sigma']['translation_mm'] == pytest.approx(3.0)


def test_predictions_carried_to_more_data_are_ready_only_inside_the_margin() -> None:
    """Carried from a result to the buffers that grew since, 9 mm against 10 is not READY:
    the next calibration measures its sigmas again on four blocks (BLOCKS_MARGIN, 0.81);
    7 mm is."""
    assert BLOCKS_MARGIN == pytest.approx(1 / (1 + 1 / np.sqrt(18)))
    near = carry_over(_ready({**SIGMA, 'translation_mm': 9.0}), {'translation_mm': 1.0}, [])
    assert near['ready']  # the result's own data: the targets as they are
    grown = carry_over(
        _ready({**SIGMA, 'translation_mm': 9.0}),
        {'translation_mm': 1.0},
        [],
        margin=BLOCKS_MARGIN,
    )
    assert not grown['ready'] and 'READY within 81% of the targets' in grown['missing'][0]
    inside = carry_over(
        _ready({**SIGMA, 'translation_mm': 7.0}),
        {'translation_mm': 1.0},
        [],
        margin=BLOCKS_MARGIN,
    )
    assert inside['ready']


def test_a_last_calibration_doubtful_for_another_reason_holds_ready_back() -> None:
    held = carry_over(_ready(SIGMA), {}, ['the residuals are strongly correlated in time'])
    assert not held['ready']
    assert held['missing'] == [
        'the last calibration is doubtful: the residuals are strongly correlated in time'
    ]


def test_a_last_calibration_not_good_for_its_precision_holds_ready_back() -> None:
    # READY says that a calibration now would be good: predictions carried from an imprecise
    # result (V2_02 stereo's prefixes: 8.7 mm carried, 10.5 mm calibrated) do not say it
    document = {
        'quality': {
            'reasons': [
                {'code': 'imprecise', 'message': 'translation 1-sigma 10.5 mm'},
                {'code': 'residuals_not_white', 'message': 'the residuals are correlated'},
            ]
        }
    }
    held = held_reasons(document)
    assert held == ['the residuals are correlated', 'translation 1-sigma 10.5 mm']
    last = _ready({'time_offset_ms': 0.2, 'translation_mm': 8.7, 'rotation_deg': 0.2})
    status = carry_over(last, {}, held[1:])
    assert not status['ready']
    assert status['missing'][0] == 'the last calibration is doubtful: translation 1-sigma 10.5 mm'


def test_a_result_whose_sigmas_lack_the_blocks_holds_ready_back() -> None:
    """A `good` result of too few eye poses for the blocks (EuRoC MH_01 stereo's first 15 s:
    8.8 mm, then 16.6 mm with the blocks at 20 s, where a READY carried from it was wrong)
    holds READY back as a doubtful one does, said as what it lacks; one with the blocks'
    factors does not."""
    document = {'quality': {'reasons': []}, 'std': {'block_factors': None}}
    held = held_reasons(document)
    assert held == [LACKS_BLOCKS]
    status = carry_over(_ready(SIGMA), {}, held)
    assert not status['ready']
    assert status['missing'][0] == f'the last calibration {LACKS_BLOCKS}'
    measured = {'quality': {'reasons': []}, 'std': {'block_factors': {'translation': 1.4}}}
    assert held_reasons(measured) == []


def test_a_results_own_readiness_is_ready_only_when_it_is_good() -> None:
    """An offset that wanders by 10 ms along 60 s: the consecutive pairs predict 0.18 ms and
    READY, the result reports 2.1 ms and is doubtful. Its ``readiness`` says NOT READY with the
    reported sigmas and why; a result that is good stays READY with its own sigmas."""
    rec = recording(0, 2, duration_s=60.0, wander_s=0.010)
    res = calibrate(rec.hand, rec.eye)
    assert res.readiness.ready and res.quality.label().startswith('doubtful')
    d = res.to_dict()['readiness']
    assert not d['ready']
    assert d['predicted'] == res.readiness.to_dict()['sigma']
    assert d['sigma']['time_offset_ms'] == pytest.approx(res.batch.std[0] * 1e3)
    assert d['missing'][0].startswith('this calibration is doubtful: ')
    lines = readiness_lines(d)
    assert lines[0].startswith('readiness: NOT READY, 1-sigma ')
    assert 'the consecutive poses predicted 0.18 / ' in lines[0]
    rich = recording(3, 5, duration_s=60.0)
    good = calibrate(rich.hand, rich.eye)
    g = good.to_dict()['readiness']
    assert good.quality.label() == 'good' and g['ready']
    assert g['sigma']['translation_mm'] == pytest.approx(np.linalg.norm(good.batch.std[1:4]) * 1e3)
