"""Package layout rules: the core runs without ROS; the shipped files agree with each other."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET

from conftest import ROOT, run_cli


def test_core_and_offline_tool_do_not_import_rclpy() -> None:
    # nor evo: it is GPLv3 and a test-only dependency
    code = ('import sys, handeye_ros.core.pipeline, handeye_ros.core.simulate, '
            'handeye_ros.offline, handeye_ros.formats, handeye_ros.evaluation.outputs, '
            'handeye_ros.evaluation.plots, handeye_ros.evaluation.html; '
            'print(sorted(m for m in sys.modules if m.split(".")[0] in ("rclpy", "rosbags", '
            '"evo")))')
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, env=env,
                         check=True, cwd=ROOT).stdout.strip()
    assert out == '[]'


def test_package_xml_and_setup_agree() -> None:
    root = ET.parse(ROOT / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == 'handeye_ros'
    assert root.find('export/build_type').text == 'ament_python'
    setup = (ROOT / 'setup.py').read_text()
    assert "version='" + root.findtext('version') + "'" in setup
    assert (ROOT / 'resource' / 'handeye_ros').is_file()
    assert 'install_scripts=$base/lib/handeye_ros' in (ROOT / 'setup.cfg').read_text()


def test_every_pin_lives_in_requirements_txt() -> None:
    setup = (ROOT / 'setup.py').read_text()
    assert not re.search(r"'[\w\-\[\]]+\s*[=<>~]=", setup), 'versions belong in requirements.txt'
    pins = [ln for ln in (ROOT / 'requirements.txt').read_text().splitlines()
            if ln and not ln.startswith('#')]
    assert all('==' in ln for ln in pins)


def test_demo_runs() -> None:
    res = run_cli('--duration', '30', module='handeye_ros.demo')
    assert res.returncode == 0, res.stderr
    assert 'result beside the truth' in res.stdout
