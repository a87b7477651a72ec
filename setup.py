import runpy
import sys
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

package_name = "contouring_ros"
# the node catalogue, read by path: building the package imports neither it nor numpy or rclpy
CATALOGUE = runpy.run_path(str(Path(__file__).resolve().parent / package_name / "wire" / "catalogue.py"))

setup(
    name=package_name,
    version="0.1.0",
    python_requires=">=3.11",
    packages=find_packages(exclude=["tests"]),
    package_data={f"{package_name}.run": ["fastdds_profile.xml", "fastdds_profile_network.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{package_name}"]),
        (f"share/{package_name}", ["package.xml"]),
        (f"share/{package_name}/config", glob("config/*.yaml")),
        (f"share/{package_name}/config/claims", glob("config/claims/*.yaml")),
        (f"share/{package_name}/config/parts", glob("config/parts/*.ngc")),
        (f"share/{package_name}/config/benchmark", glob("config/benchmark/*.yaml")),
        (f"share/{package_name}/launch", glob("launch/*.launch.py")),
    ],
    install_requires=["setuptools", "numpy", "scipy", "PyYAML", "mcap", "mcap-ros2-support", "tqdm", "ruckig", "matplotlib",
                      "cma", "control", "osqp"],
    extras_require={"test": ["pytest"], "cluster": ["distributed"], "fast": ["numba"]},
    zip_safe=True,
    maintainer="contouring_ros maintainers",
    maintainer_email="maintainers@contouring-ros.org",
    description="Multi-axis contouring control of CNC feed drives as a graph of rclpy nodes",
    license="Apache-2.0",
    entry_points={
        # colcon: plant, servo ... in lib/contouring_ros for `ros2 run`; pip: contouring-ros-plant ... on the PATH
        "console_scripts": CATALOGUE["console_scripts"](sys.argv),
    },
)
