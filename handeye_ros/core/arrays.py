"""The array types of the core's signatures (numpy.typing's ``NDArray`` of one dtype).

``Floats`` holds floating-point values (float64 throughout: poses, rates, seconds after a
common origin), ``Stamps`` int64 nanoseconds, ``Indices`` row numbers (numpy's intp, what
``flatnonzero`` and ``searchsorted`` return), ``Mask`` booleans (which rows to keep) and
``Bytes`` a file's bytes (the readers of :mod:`handeye_ros.formats`). The
bit width stays open where numpy's stubs leave it open (``np.linalg.solve`` returns
``floating[Any]``). Shapes are in each function's docstring, as scipy.spatial.transform writes
them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

Floats = npt.NDArray[np.floating[Any]]
Stamps = npt.NDArray[np.int64]
Indices = npt.NDArray[np.integer[Any]]
Mask = npt.NDArray[np.bool_]
Bytes = npt.NDArray[np.uint8]
