"""colcon build --symlink-install places every node where `ros2 run` looks, with the ament index."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ['robot_bridge', 'flex_ident', 'rod_deploy']


def console_scripts(pkg):
    text = (ROOT / 'ros_ws' / 'src' / pkg / 'setup.py').read_text()
    return re.findall(r"'([\w\-]+) = [\w.]+:\w+'", text)


def ros2_run_path(prefixes, pkg, exe):
    """How `ros2 run PKG EXE` resolves an executable: the ament index prefix, then lib/PKG/EXE."""
    for prefix in prefixes:
        if (Path(prefix) / 'share/ament_index/resource_index/packages' / pkg).exists():
            return Path(prefix) / 'lib' / pkg / exe
    return None


@pytest.mark.skipif(shutil.which('colcon', path=os.path.dirname(sys.executable)) is None,
                    reason='colcon is installed by make setup')
def test_colcon_build_installs_every_node_where_ros2_run_looks(tmp_path):
    colcon = os.path.join(os.path.dirname(sys.executable), 'colcon')
    result = subprocess.run(
        [colcon, '--log-base', str(tmp_path / 'log'), 'build', '--symlink-install',
         '--base-paths', str(ROOT / 'ros_ws' / 'src'), '--build-base', str(tmp_path / 'build'),
         '--install-base', str(tmp_path / 'install')],
        cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    prefixes = [tmp_path / 'install' / pkg for pkg in PACKAGES]
    for pkg in PACKAGES:
        scripts = console_scripts(pkg)
        assert scripts, pkg
        for exe in scripts:
            path = ros2_run_path(prefixes, pkg, exe)
            assert path is not None and path.is_file() and os.access(path, os.X_OK), (pkg, exe)
    for pkg in PACKAGES:            # the launch files (not run here: no `launch` package) are installed and parse
        sources = sorted((ROOT / 'ros_ws' / 'src' / pkg / 'launch').glob('*.launch.py'))
        assert sources, pkg
        for source in sources:
            installed = tmp_path / 'install' / pkg / 'share' / pkg / 'launch' / source.name
            assert installed.is_file(), installed
            compile(installed.read_text(), str(installed), 'exec')
    help_run = subprocess.run([str(ros2_run_path(prefixes, 'robot_bridge', 'bag-tools')), '--help'],
                              capture_output=True, text=True, timeout=60)
    assert help_run.returncode == 0 and 'import-csv' in help_run.stdout
