"""From the command line to the printed result (issue 67): the package's modules that
``python -m handeye_ros.offline --hand A --eye B`` imports, and its deepest stack of package
frames, on the built-in example's recording (``handeye_ros.app.demo --keep``).

Usage: python bench/code_path.py
"""

from __future__ import annotations

import pkgutil
import runpy
import sys
import tempfile
from pathlib import Path

import common  # noqa: F401  (first: puts the project on sys.path)
from common import emit, table

import handeye_ros
from handeye_ros.app import demo

PACKAGE = str(Path(handeye_ros.__file__).parent)


def _depth(frame) -> int:
    d = 0
    while frame is not None:
        d += frame.f_code.co_filename.startswith(PACKAGE)
        frame = frame.f_back
    return d


def main() -> None:
    deepest = [0, '']

    def profile(frame, event, _arg) -> None:
        if event == 'call' and frame.f_code.co_filename.startswith(PACKAGE):
            d = _depth(frame)
            if d > deepest[0]:
                where = frame.f_code.co_filename[len(PACKAGE) + 1 :]
                deepest[:] = [d, f'{where}:{frame.f_code.co_name}']

    with tempfile.TemporaryDirectory() as tmp:
        demo.main(['--keep', tmp, '--text'])
        before = {m for m in sys.modules if m.startswith('handeye_ros')}
        for m in before - {'handeye_ros'}:
            del sys.modules[m]
        sys.argv = ['offline', '--hand', f'{tmp}/hand_mocap.txt', '--eye', f'{tmp}/eye_vio.txt']
        sys.argv += ['--output', f'{tmp}/out.yaml']
        sys.setprofile(profile)
        try:
            runpy.run_module('handeye_ros.offline', run_name='__main__')
        except SystemExit:
            pass
        finally:
            sys.setprofile(None)
    imported = sum(m.startswith('handeye_ros.') for m in sys.modules)
    total = sum(1 for _ in pkgutil.walk_packages(handeye_ros.__path__, 'handeye_ros.'))
    emit(
        'code_path',
        table(
            'python -m handeye_ros.offline --hand A --eye B: the package on its path',
            ['modules imported', 'of the package', 'deepest package frames', 'at'],
            [[imported, total, deepest[0], deepest[1]]],
        ),
    )


if __name__ == '__main__':
    main()
