"""The demo (scripts/demo, the README's first command) on a simulated rig."""

from __future__ import annotations

import pytest
from conftest import run_cli


@pytest.mark.slow
def test_demo_runs() -> None:
    res = run_cli('--duration', '30', module='handeye_ros.app.demo')
    assert res.returncode == 0, res.stderr
    assert 'result beside the truth' in res.stdout
