"""Lint, format and types: ruff over the package, the tests and the benchmarks (ruff.toml); mypy
over the package (setup.cfg's [mypy])."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from conftest import ROOT

# the source, read: the same in every venv (setup.cfg's markers)
pytestmark = pytest.mark.static


def _tool(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    """``python -m TOOL ARGS`` at the repository root, its output captured."""
    return subprocess.run(
        [sys.executable, '-m', *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def test_ruff_is_clean() -> None:
    pytest.importorskip('ruff', reason='ruff not installed (requirements.txt pins it)')
    proc = _tool('ruff', 'check', '--no-cache', 'handeye_ros', 'test', 'bench')
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_ruff_format_is_clean() -> None:
    pytest.importorskip('ruff', reason='ruff not installed (requirements.txt pins it)')
    proc = _tool('ruff', 'format', '--check', '--no-cache', 'handeye_ros', 'test', 'bench')
    assert proc.returncode == 0, 'run `ruff format handeye_ros test bench`:\n' + proc.stdout


def test_mypy_finds_no_error_in_the_package() -> None:
    pytest.importorskip('mypy', reason='mypy not installed (requirements.txt pins it)')
    # no cache: the two suites of .ci/run check the same checkout at once
    proc = _tool('mypy', '--cache-dir', os.devnull, timeout=300.0)
    assert proc.returncode == 0, proc.stdout + proc.stderr
