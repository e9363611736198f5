"""The golden regression test: every number and verdict of bench/same_results.py's short cases
(the built-in example; the simulator at noise levels 0, 5 and 10 with the default options and
each stage switch that takes another path), as the front ends return them (the evaluation's
figures with their error bars from the calibration, and the verdict judged with them), against
their records in test/golden/, one per platform (``python bench/same_results.py golden`` writes
this platform's).

- The verdicts, the purposes judged and the reasons' codes (and a refusal) are the same as every
  platform's record.
- Every field of the record of this platform is the same, numbers within NUMBERS_TOLERANCE:
  on one platform a calibration sums in one order whatever the CPU, but for the last bits of
  libm and OpenBLAS's kernels (9.1e-9 at most between OpenBLAS's SkylakeX, Haswell and
  Sandybridge kernels over same_results' 45 cases, on an RPE figure of the evaluation;
  docs/benchmarks.md). Between platforms the numbers are not compared: numpy 1.26 / scipy 1.11
  against today's pins move the linear stage's singular values of a noisy scale case by up to
  9e-4 of themselves, with the same verdicts.

A change of behaviour records them again, and its commit says which cases moved and why.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from conftest import ROOT

sys.path.insert(0, str(ROOT / 'bench'))
import same_results

#: Numbers of this platform's record: |a - b| <= this * max(1, |a|, |b|).
NUMBERS_TOLERANCE = 1e-6
RECORDS = sorted((ROOT / 'test' / 'golden').glob('same_results-*.json'))


@pytest.fixture(scope='module')
def now() -> dict:
    """This tree's results, through the JSON round trip the records took."""
    return json.loads(json.dumps(same_results.record(short=True)))


@pytest.mark.parametrize('path', RECORDS, ids=lambda p: p.stem.removeprefix('same_results-'))
def test_the_verdicts_are_every_platforms(path: Path, now: dict) -> None:
    before = json.loads(path.read_text())['results']
    moved = same_results.compare(same_results.verdicts(before), same_results.verdicts(now))
    assert not moved, '\n'.join(moved)


def test_the_numbers_are_this_platforms(now: dict) -> None:
    path = same_results.golden_file()
    if not path.is_file():
        pytest.skip(f'no golden record for this platform ({path.name})')
    before = json.loads(path.read_text())['results']
    moved = same_results.compare(before, now, NUMBERS_TOLERANCE)
    assert not moved, '\n'.join(moved[:40])
