"""The screening's running median: scipy's median_filter (mode 'mirror') value for value, on
every scipy, by the pairs of blocks where scipy's filter selects each window anew."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.ndimage import median_filter

from handeye_ros.core.checks import running_median as rm


@settings(max_examples=200, deadline=None)
@given(
    n=st.integers(min_value=3, max_value=900),
    fraction=st.floats(min_value=0.0, max_value=1.0),
    decimals=st.sampled_from([None, 0, 1]),
    spikes=st.integers(min_value=0, max_value=5),
    seed=st.integers(min_value=0, max_value=2**31),
)
def test_the_pairs_of_blocks_give_scipys_values(
    n: int, fraction: float, decimals: int | None, spikes: int, seed: int
) -> None:
    """Any odd window up to the signal's length, ties (rounded values) and wild values
    included: the same floats as median_filter."""
    rng = np.random.default_rng(seed)
    size = max(1, min(n, round(fraction * n)) | 1)
    if size > n:
        size -= 2
    x = rng.standard_normal(n)
    if decimals is not None:
        x = np.round(x, decimals)
    x[rng.integers(0, n, spikes)] = 1e6
    expected = median_filter(x, size=size, mode='mirror')
    assert np.array_equal(rm._pairs_of_blocks(x, size), expected)
    assert np.array_equal(rm.running_median(x, size), expected)


def test_a_long_signal_takes_the_pairs_only_where_scipy_is_slow() -> None:
    """The screening's own case (22 401 residuals, windows of 401) through the public call."""
    x = np.abs(np.random.default_rng(3).standard_normal(22_401))
    assert x.size >= rm.PAIRS_FROM
    np.testing.assert_array_equal(rm.running_median(x, 401), median_filter(x, 401, mode='mirror'))
