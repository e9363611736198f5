"""Which params-file sections apply to the node (rcl's wildcards), as the node's warning about
a params file with none for it reads them."""

from __future__ import annotations

import pytest

pytest.importorskip('rclpy')

from handeye_ros.app.params_file import PARAMS_SECTION
from handeye_ros.ros.parameters import section_applies


@pytest.mark.parametrize(
    ('section', 'node', 'applies'),
    [
        ('/**', '/calibrator', True),
        ('/**', '/rig/calibrator', True),
        (PARAMS_SECTION, '/calibrator', True),
        (PARAMS_SECTION, '/rig/left/calibrator', True),
        (PARAMS_SECTION, '/calibrator2', False),
        ('calibrator', '/calibrator', True),
        ('calibrator', '/rig/calibrator', False),
        ('/*/calibrator', '/rig/calibrator', True),
        ('/*/calibrator', '/calibrator', False),
        ('calibratr', '/calibrator', False),
    ],
)
def test_a_params_file_section_applies_by_rcl_wildcards(
    section: str, node: str, applies: bool
) -> None:
    assert section_applies(section, node) is applies
