"""The ament_python package builds with colcon and installs an executable per node where ros2 run looks."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from contouring_ros.wire import catalogue
from conftest import ROOT

NODES = [node.console_script for node in catalogue.NODES]


@pytest.mark.slow
@pytest.mark.parametrize("options", [[], ["--symlink-install"]], ids=["copy", "symlink"])
def test_colcon_build_installs_every_node(tmp_path, options):
    colcon = shutil.which("colcon") or str(Path(sys.executable).parent / "colcon")
    if not os.path.exists(colcon):
        pytest.fail("colcon is not installed (pip install colcon-core colcon-ros)")
    src = tmp_path / "src" / "contouring_ros"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".git", ".venv", "build", "install", "log", "bags",
                                                              "__pycache__", "*.egg-info", "reports"))
    result = subprocess.run([colcon, "build", "--base-paths", "src", *options], cwd=tmp_path, capture_output=True,
                            text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    prefix = tmp_path / "install" / "contouring_ros"
    # ros2 run <pkg> <exe> finds the package prefix through the ament index, then looks in lib/<pkg>.
    marker = prefix / "share" / "ament_index" / "resource_index" / "packages" / "contouring_ros"
    assert marker.is_file()
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix))
    found = subprocess.run([sys.executable, "-c", "from ament_index_python.packages import get_package_prefix;"
                            "print(get_package_prefix('contouring_ros'))"], env=env, capture_output=True, text=True)
    assert found.stdout.strip() == str(prefix), found.stderr
    for node in NODES:
        executable = prefix / "lib" / "contouring_ros" / node
        assert executable.is_file() and os.access(executable, os.X_OK), node
    assert list((prefix / "share" / "contouring_ros" / "config").glob("paper000_*.yaml"))
    assert (prefix / "share" / "contouring_ros" / "launch" / "contouring.launch.py").is_file()
    # the README's recipe sources a script this colcon wrote (colcon-core writes setup.sh; setup.bash only
    # with colcon-bash)
    import re
    sourced = re.findall(r"colcon build && source (install/\S+)", (ROOT / "README.md").read_text())
    assert sourced and all((tmp_path / name).is_file() for name in sourced), sourced


def test_package_xml_declares_the_launch_file_s_packages():
    """The installed launch file imports launch and launch_ros: package.xml names both (rosdep installs them)."""
    xml = (ROOT / "package.xml").read_text()
    launch = (ROOT / "launch" / "contouring.launch.py").read_text()
    for package in ("launch", "launch_ros"):
        assert f"import {package}" in launch or f"from {package}" in launch
        assert f"<exec_depend>{package}</exec_depend>" in xml, package


def test_the_code_cites_only_documents_in_the_repository():
    """Every Markdown document the code names is a file of the repository (its docs, or a report it writes),
    and every section of docs/ARCHITECTURE.md it names exists there."""
    import re
    architecture = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    sections = set(re.findall(r"^#+ (.+)$", architecture, re.M))
    for path in (ROOT / "contouring_ros").rglob("*.py"):
        text = path.read_text()
        for document in set(re.findall(r"[\w./-]*[A-Za-z]\.md\b", text)):
            assert any((ROOT / folder / document).is_file() for folder in ("", "docs", "reports")), \
                f"{path.name} cites {document}, which the repository lacks"
        for section in re.findall(r'ARCHITECTURE\.md, "([^"]+)"', text):
            assert section in sections, f"{path.name} cites a section {section!r} that docs/ARCHITECTURE.md lacks"


def test_package_xml_declares_what_setup_py_installs():
    """Every install requirement has a rosdep key in package.xml, or is one of the pip-only packages the
    README's ROS recipe installs with pip."""
    import re
    xml = (ROOT / "package.xml").read_text()
    setup = (ROOT / "setup.py").read_text()
    required = re.search(r"install_requires=\[(.*?)\]", setup, re.S).group(1)
    pip_only = {"mcap", "mcap-ros2-support", "ruckig", "cma", "control", "osqp"}
    keys = {"setuptools": None, "PyYAML": "python3-yaml"}
    for name in re.findall(r'"([^"]+)"', required):
        if name in pip_only:
            assert f"pip install {' '.join(sorted(pip_only))}" in (ROOT / "README.md").read_text()
            continue
        key = keys.get(name, f"python3-{name.lower()}")
        assert key is None or f"<exec_depend>{key}</exec_depend>" in xml, name


def test_every_subcommand_prints_its_help(capsys):
    """``contouring-ros COMMAND --help`` prints a help text and exits 0 for every subcommand (a help string
    with a bare % once made argparse raise instead)."""
    from contouring_ros import cli
    with pytest.raises(SystemExit) as done:
        cli.main(["--help"])
    assert done.value.code == 0
    commands = capsys.readouterr().out.split("{", 1)[1].split("}", 1)[0].split(",")
    assert "benchmark" in commands and "run" in commands
    for command in commands:
        with pytest.raises(SystemExit) as done:
            cli.main([command, "--help"])
        assert done.value.code == 0, command
        assert capsys.readouterr().out.startswith(f"usage: contouring-ros {command}"), command
