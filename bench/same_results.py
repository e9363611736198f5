"""Same results before and after a refactor (issue 14): record every number a calibration
returns on a fixed set of cases, as the front ends return it (the evaluation's APE/RPE figures
with their error bars from the calibration, and the verdict judged with them for the purpose),
then compare another commit's numbers with them to 1e-9.

Cases: the built-in example (handeye_ros.app.demo's recording), the simulator at noise levels 0, 5
and 10 with the default configuration and with each stage switch that takes another code path
(linear only, the joint batch solve, clock drift, scale, the paper's dual-quaternion solution,
no RANSAC), 10 minutes of 1 kHz MoCap and 200 Hz VIO (the paths only long recordings take: eye
pairs in several chunks, the caps on what the checks read), with and without a clock drift, and
the semi-synthetic real pairs of bench/cases.py (skipped without the data).

Usage:
    python bench/same_results.py record FILE     # numbers of this tree, as JSON
    python bench/same_results.py compare FILE    # this tree against FILE; exit 1 on a difference
    python bench/same_results.py compare FILE --tolerance 1e-6
    python bench/same_results.py verdicts FILE   # only the verdicts and reason codes differ?
    python bench/same_results.py golden          # the short cases into test/golden/ (the test's)

A field differs when ``|a - b| > tolerance * max(1, |a|, |b|)`` (1e-9 unless given); run times
and anything measured in seconds of the machine are left out. Across library versions (today's
pins against the Jazzy platform's numpy 1.26 / scipy 1.11: ``scripts/setup --jazzy``), the
same code sums in another order (BLAS, LAPACK, pocketfft), so compare there with the tolerance
that order allows; the comparison prints the largest relative difference it saw.
"""

from __future__ import annotations

import json
import math
import re
import sys
from dataclasses import replace
from pathlib import Path

import cases
import common  # first: puts the project on sys.path

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.evaluation.outputs import evaluate_and_write

TOLERANCE = 1e-9
#: The records test/test_golden.py holds every tree to (``golden``: the short cases), one per
#: platform (numpy and scipy versions: the same code sums in another order on another).
GOLDEN = Path(__file__).resolve().parents[1] / 'test' / 'golden'


def golden_file() -> Path:
    """This platform's golden record."""
    import numpy as np
    import scipy

    return GOLDEN / f'same_results-numpy{np.__version__}-scipy{scipy.__version__}.json'


#: Keys whose values are machine time, not results.
VOLATILE = ('seconds', 'runtime', 'elapsed', 'wall')
VARIANTS = {
    'default': {},
    'linear': {'batch': False},
    'drift': {'clock_drift': True},
    'scale': {'estimate_scale': True},
    'paper_dq': {'decoupled_refit': False, 'adaptive_inliers': False, 'batch': False},
    'no_ransac': {'ransac_iterations': 0, 'batch': False},
}
DEMO_SEED, DEMO_LEVEL, DEMO_DURATION = 7, 5.0, 60.0  # handeye_ros/app/demo.py's defaults
LONG_SEED, LONG_DURATION = 300, 600.0


def every_case(short: bool = False):
    """(name, hand, eye, config) of every case; ``short``: the simulated ones of a minute or
    less, the golden regression test's (test/test_golden.py)."""
    base = CalibrationConfig()
    rec = cases.recording(DEMO_SEED, DEMO_LEVEL, duration_s=DEMO_DURATION)
    yield 'demo', rec.hand, rec.eye, base
    for level in (0, 5, 10):
        rec = cases.recording(100 + level, level, duration_s=40.0)
        for name, change in VARIANTS.items():
            yield f'sim L{level} {name}', rec.hand, rec.eye, replace(base, **change)
    if short:
        return
    for name, drift in (('default', 0.0), ('drift', 5e-5)):
        rec = cases.recording(
            LONG_SEED,
            5,
            duration_s=LONG_DURATION,
            hand_rate_hz=1000.0,
            eye_rate_hz=200.0,
            clock_drift=drift,
        )
        yield f'sim 1 kHz 10 min {name}', rec.hand, rec.eye, replace(base, **VARIANTS[name])
    if cases.available():
        for pair in cases.PAIRS:
            gt, est = cases.load(pair)
            hand = cases.to_marker_frame(gt, cases.SHIFT_S)
            for name in ('default', 'linear'):
                yield f'{pair.name} {name}', hand, est, replace(base, **VARIANTS[name])


def flatten(value, prefix: str = '') -> dict:
    """Leaves of nested dicts and lists, keyed by their path; volatile keys left out."""
    out = {}
    if isinstance(value, dict):
        for k, v in value.items():
            if not any(word in str(k) for word in VOLATILE):
                out.update(flatten(v, f'{prefix}/{k}'))
    elif isinstance(value, (list, tuple)):
        for k, v in enumerate(value):
            out.update(flatten(v, f'{prefix}/{k}'))
    elif isinstance(value, str):
        out[prefix] = _portable(value)
    else:
        out[prefix] = value
    return out


def _portable(text: str) -> str:
    """The data folder's path differs between checkouts."""
    return re.sub(r'\S*/shared/data/real/', '<real>/', text)


def document(hand, eye, cfg: CalibrationConfig) -> dict:
    """The result document the front ends give (offline, the node, evaluate): the calibration,
    its evaluation with the figures' error bars, and the verdict judged with them."""
    res = calibrate(hand, eye, cfg)
    out = res.to_dict()
    evaluate_and_write(res, out)
    return dict(out)


def record(short: bool = False) -> dict:
    results = {}
    for name, hand, eye, cfg in every_case(short):
        try:
            results[name] = flatten(document(hand, eye, cfg))
        except HandeyeError as err:
            results[name] = {'/error': str(err)}
        print(name, file=sys.stderr, flush=True)
    return results


def relative(a, b) -> float:
    """|a - b| / max(1, |a|, |b|) of two numbers (0 for two NaN, inf for one)."""
    if math.isnan(a) or math.isnan(b):
        return 0.0 if math.isnan(a) and math.isnan(b) else math.inf
    return abs(a - b) / max(1.0, abs(a), abs(b))


def _numbers(a, b) -> bool:
    return (
        isinstance(a, (int, float))
        and isinstance(b, (int, float))
        and not isinstance(a, bool)
        and not isinstance(b, bool)
    )


def differs(a, b, tolerance: float = TOLERANCE) -> bool:
    if _numbers(a, b):
        return relative(a, b) > tolerance
    if isinstance(a, str) and isinstance(b, str):
        return _portable(a) != _portable(b)
    return a != b


def compare(before: dict, after: dict, tolerance: float = TOLERANCE) -> list[str]:
    lines = []
    for case in sorted(set(before) | set(after)):
        b, a = before.get(case), after.get(case)
        if a is None or b is None:
            lines.append(f'{case}: only {"before" if a is None else "after"}')
            continue
        for key in sorted(set(a) | set(b)):
            if key not in a or key not in b:
                lines.append(f'{case} {key}: only {"before" if key not in a else "after"}')
            elif differs(b[key], a[key], tolerance):
                lines.append(f'{case} {key}: {b[key]!r} -> {a[key]!r}')
    return lines


#: What ``verdicts`` compares: the verdict, each purpose's, the reasons' codes, a refusal.
VERDICT_KEY = re.compile(
    r'^/quality/(verdict|purpose|reasons/\d+/code|for_\w+/(verdict|codes/\d+))$|^/error$'
)


def verdicts(results: dict) -> dict:
    """Of every case, only what :data:`VERDICT_KEY` names (a refusal as refused)."""
    return {
        case: {
            k: ('refused' if k == '/error' else v) for k, v in r.items() if VERDICT_KEY.match(k)
        }
        for case, r in results.items()
    }


def largest(before: dict, after: dict) -> tuple[float, str]:
    """The largest relative difference of the numbers both hold, and where."""
    worst = (0.0, '-')
    for case in set(before) & set(after):
        b, a = before[case], after[case]
        for key in set(a) & set(b):
            if _numbers(b[key], a[key]):
                worst = max(worst, (relative(b[key], a[key]), f'{case} {key}'))
    return worst


def main() -> int:
    args = sys.argv[1:]
    if args == ['golden']:  # the golden regression test's record of this platform
        now = json.loads(json.dumps(record(short=True)))
        path = golden_file()
        path.write_text(json.dumps({'provenance': common.provenance(), 'results': now}, indent=1))
        print(f'{len(now)} cases recorded in {path}')
        return 0
    tolerance = TOLERANCE
    if len(args) == 4 and args[2] == '--tolerance':
        tolerance = float(args.pop())
        args.pop()
    if len(args) != 2 or args[0] not in ('record', 'compare', 'verdicts'):
        print(__doc__.split('Usage:')[1].strip(), file=sys.stderr)
        return 2
    path = Path(args[1])
    now = json.loads(json.dumps(record()))  # the same float round trip as the file
    if args[0] == 'record':
        path.write_text(json.dumps({'provenance': common.provenance(), 'results': now}, indent=1))
        print(f'{len(now)} cases recorded in {path}')
        return 0
    before = json.loads(path.read_text())
    if args[0] == 'verdicts':  # another BLAS kernel or library: the numbers' last digits move
        lines = compare(verdicts(before['results']), verdicts(now))
        print('\n'.join(lines) if lines else f'{len(now)} cases: the same verdicts and reasons')
        return 1 if lines else 0
    lines = compare(before['results'], now, tolerance)
    print(f'before: {before["provenance"]}\nafter:  {common.provenance()}')
    print('\n'.join(lines) if lines else f'{len(now)} cases: the same to {tolerance:g}')
    worst, where = largest(before['results'], now)
    print(f'largest relative difference: {worst:.2g} ({where})')
    return 1 if lines else 0


if __name__ == '__main__':
    sys.exit(main())
