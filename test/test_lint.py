"""Lint, format and types: ruff over the package, the tests and the benchmarks (ruff.toml); mypy
over the package (setup.cfg's [mypy])."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from conftest import ROOT


def test_ruff_is_clean() -> None:
    pytest.importorskip('ruff', reason='ruff not installed (requirements.txt pins it)')
    proc = subprocess.run(
        [sys.executable, '-m', 'ruff', 'check', '--no-cache', 'handeye_ros', 'test', 'bench'],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_ruff_format_is_clean() -> None:
    pytest.importorskip('ruff', reason='ruff not installed (requirements.txt pins it)')
    proc = subprocess.run(
        [
            sys.executable,
            '-m',
            'ruff',
            'format',
            '--check',
            '--no-cache',
            'handeye_ros',
            'test',
            'bench',
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, 'run `ruff format handeye_ros test bench`:\n' + proc.stdout


def test_mypy_finds_no_error_in_the_package() -> None:
    pytest.importorskip('mypy', reason='mypy not installed (requirements.txt pins it)')
    # no cache: the two suites of .ci/run check the same checkout at once
    proc = subprocess.run(
        [sys.executable, '-m', 'mypy', '--cache-dir', os.devnull],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
