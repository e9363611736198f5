"""The same inputs give the same bits, wherever numpy happens to allocate.

numpy 1.26 (the Jazzy platform's) runs its transcendental ufuncs through SIMD kernels (SVML on
AVX-512) or libm's scalar loop, whichever its overlap check allows. For a strided input view
that check counts stride x length, past the view's last element, so an output that the
allocator happens to place right after the input's block sends the call to libm, which differs
from the SIMD kernel in the last ulp. A calibration then differed in the 16th digit from one
process to the next (the node's live result against its own bag replayed offline). Contiguous
inputs never trip the check; the core gives these ufuncs nothing else.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import keyframes_only, noise_level, simulate, with_dropouts
from handeye_ros.evaluation.aligned import calibrated, uncalibrated
from handeye_ros.evaluation.metrics import Evaluation

#: numpy's float64 ufuncs with a SIMD kernel whose last bits may differ from libm's.
SIMD_UFUNCS = (
    'arctan2', 'power', 'hypot', 'exp', 'log', 'exp2', 'log2', 'log10', 'expm1', 'log1p',
    'cbrt', 'sin', 'cos', 'tan', 'arcsin', 'arccos', 'arctan', 'sinh', 'cosh', 'tanh',
    'arcsinh', 'arccosh', 'arctanh',
)  # fmt: skip


@pytest.mark.parametrize('name', SIMD_UFUNCS)
def test_contiguous_inputs_give_the_same_bits_wherever_the_output_lies(name: str) -> None:
    ufunc = getattr(np, name)
    rng = np.random.default_rng(0)
    x = rng.uniform(1.1, 1.9, (2, 4000))  # in every function's domain
    buf = np.empty(3 * 4000)
    args = tuple(np.ascontiguousarray(v) for v in x[: ufunc.nin])
    buf[:4000] = args[0]
    # the output right after the input's block (past malloc's 16-byte header), and elsewhere
    near, far = buf[4002:8002], np.empty(4000)
    ufunc(buf[:4000], *args[1:], out=near)
    ufunc(buf[:4000], *args[1:], out=far)
    assert near.tobytes() == far.tobytes()


class _Contiguous:
    """A numpy ufunc that refuses a strided array input (its methods pass through)."""

    def __init__(self, ufunc: Any):
        self._ufunc = ufunc

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        for a in args:
            if isinstance(a, np.ndarray) and a.size > 1 and not a.flags.c_contiguous:
                raise AssertionError(f'np.{self._ufunc.__name__} given a strided view')
        return self._ufunc(*args, **kwargs)

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._ufunc, attr)


@pytest.fixture
def contiguous_only(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in SIMD_UFUNCS:
        monkeypatch.setattr(np, name, _Contiguous(getattr(np, name)))


def _cases():
    nm, nd = noise_level(3)
    rec = simulate(3, duration_s=40, hand_rate_hz=200, eye_rate_hz=30, noise_m=nm, noise_deg=nd)
    rng = np.random.default_rng(1)
    yield 'default', rec.hand, rec.eye, CalibrationConfig()
    yield 'drift', rec.hand, rec.eye, CalibrationConfig(clock_drift=True)
    yield 'scale', rec.hand, rec.eye, CalibrationConfig(estimate_scale=True)
    yield 'dropouts', with_dropouts(rec.hand, rng, 0.2), rec.eye, CalibrationConfig()
    long = simulate(4, duration_s=120, noise_m=nm, noise_deg=nd)
    yield 'keyframes', long.hand, keyframes_only(long.eye, rng), CalibrationConfig()


@pytest.mark.usefixtures('contiguous_only')
@pytest.mark.parametrize('case', list(_cases()), ids=lambda c: c[0])
def test_the_core_and_the_metrics_give_simd_ufuncs_contiguous_inputs(case) -> None:
    _, hand, eye, cfg = case
    result = calibrate(hand, eye, cfg)
    base, why = uncalibrated(result)
    Evaluation.of(calibrated(result), base, why=why)
