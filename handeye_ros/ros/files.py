"""What the calibrator writes, and where: only inside its ``output_dir``. No rclpy here.

Any participant of a ROS graph without SROS2 may set the node's parameters and call its
services. ``output_file``, ``report_dir`` and ``rig_file`` may therefore change at run time,
but ``output_dir``, set at start-up and read-only after, bounds them: each is a path inside it
(relative, or absolute within it), never through ``..`` or a symbolic link out of it. A file
is replaced whole (written beside it, then renamed: a symbolic link in its place is replaced,
never followed), and only when it is a result of this package (a result, a rig file, a report
page). A folder that exists keeps its mode: the report's files are copied into it one by one.
"""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path

from ..core.errors import InputError

#: ``output_dir``'s default inside ROS_HOME (``~/.ros`` when unset), where ROS keeps its logs.
DEFAULT_SUBDIR = 'handeye_ros'
#: A report page of ours holds this (evaluation.html's title).
REPORT_MARK = '<title>handeye_ros calibration report</title>'


def default_output_dir() -> str:
    """``$ROS_HOME/handeye_ros``, ``~/.ros/handeye_ros`` without ROS_HOME."""
    home = os.environ.get('ROS_HOME') or os.path.join(os.path.expanduser('~'), '.ros')
    return os.path.join(home, DEFAULT_SUBDIR)


def inside(root: str, name: str, what: str) -> Path:
    """The path ``name`` (a parameter's value, ``what`` its name) inside the folder ``root``,
    resolved; InputError, in one line, when it is empty or leads out of ``root`` (``..``, an
    absolute path elsewhere, a symbolic link out)."""
    if not name:
        raise InputError(f'{what} is empty: name a file inside output_dir {root}')
    base = Path(root).resolve()
    path = Path(name) if os.path.isabs(name) else Path(root) / name
    if '..' in Path(name).parts:
        raise InputError(f'{what} {name}: ".." is not allowed; name a path inside {base}')
    resolved = path.resolve()
    if not resolved.is_relative_to(base):
        link = ' through a symbolic link' if path.absolute().is_relative_to(base) else ''
        raise InputError(f'{what} {name}: outside output_dir {base}{link}; refused')
    return resolved


def replace_file(path: Path, write: Callable[[Path], None], ours: Callable[[Path], bool]) -> None:
    """Write ``path`` whole: ``write`` fills a new file beside it, which then takes its name.
    InputError when ``path`` exists and is not ours (``ours(path)`` false), or is a folder."""
    if path.is_dir():
        raise InputError(f'{path}: is a folder; name a file')
    if path.exists() and not path.is_symlink() and not ours(path):
        raise InputError(
            f'{path}: exists and is not a handeye_ros result; refusing to overwrite it'
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f'.{path.name}.', suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        # the mode of the file it replaces, else what open() would give (mkstemp's is 0600)
        mode = stat.S_IMODE(path.stat().st_mode) if path.is_file() else 0o666 & ~_umask()
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def is_report(path: Path) -> bool:
    """Whether ``path`` is a report page of ours."""
    try:
        with path.open(errors='replace') as f:
            return REPORT_MARK in f.read(4096)
    except OSError:
        return False


def check_report_folder(dest: Path) -> bool:
    """Whether ``dest`` holds a report of ours (False: it is new or empty); InputError when it
    holds anything else."""
    page = dest / 'report.html'
    ours = is_report(page)
    if dest.exists() and not dest.is_dir():
        raise InputError(f'{dest}: is a file; name a folder for the report')
    if not ours and dest.is_dir() and any(dest.iterdir()):
        raise InputError(f'{dest}: a folder that holds no handeye_ros report; name a new one')
    return ours


def copy_report(staged: str, dest: Path) -> None:
    """The report drawn in ``staged`` copied into ``dest`` file by file (made when missing; an
    existing folder keeps its mode; :func:`check_report_folder` first)."""
    ours = check_report_folder(dest)
    dest.mkdir(parents=True, exist_ok=True)
    for src in sorted(Path(staged).rglob('*')):
        target = dest / src.relative_to(staged)
        if src.is_dir():
            target.mkdir(exist_ok=True)
        else:
            # beside a report of ours, its plots are ours too
            replace_file(target, partial(_copy, src), lambda p: ours)


def _copy(src: Path, tmp: Path) -> None:
    """``src``'s bytes into ``tmp`` (a writer of :func:`replace_file`)."""
    shutil.copyfile(src, tmp)
