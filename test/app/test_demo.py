"""The demo (scripts/demo, the README's first command) on a simulated rig."""

from __future__ import annotations

import pytest
from conftest import run_cli

from handeye_ros.app import demo


@pytest.mark.slow
def test_demo_runs() -> None:
    res = run_cli('--duration', '30', module='handeye_ros.app.demo')
    assert res.returncode == 0, res.stderr
    assert 'result beside the truth' in res.stdout


@pytest.mark.parametrize(
    ('bad', 'said'),
    [
        (['--duration', '0'], 'holds no eye poses'),
        (['--duration', '1e9'], 'simulate less'),
        (['--level', 'nan'], "the noise level is one of the paper's"),
        (['--level', '11'], "the noise level is one of the paper's"),
        (['--seed', '-1'], 'the seed is an integer >= 0'),
        (['--keep', '/proc/demo'], '--keep /proc/demo: cannot make the folder there'),
    ],
)
def test_absurd_values_are_usage_errors(
    bad: list[str], said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Refused as argparse refuses a typo (exit 2, what is wrong), before anything is made."""
    with pytest.raises(SystemExit) as stop:
        demo.main(bad)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and said in err and 'Traceback' not in err, err
