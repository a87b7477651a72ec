from glob import glob

from setuptools import find_packages, setup

package_name = "contouring_ros"
NODES = ["interpolator", "plant", "servo", "contour_estimator", "ccc", "recorder"]

setup(
    name=package_name,
    version="0.1.0",
    python_requires=">=3.11",
    packages=find_packages(exclude=["tests"]),
    package_data={package_name: ["fastdds_profile.xml", "fastdds_profile_network.xml"]},
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
                      "cma", "control"],
    extras_require={"test": ["pytest"], "cluster": ["distributed"]},
    zip_safe=True,
    maintainer="contouring_ros maintainers",
    maintainer_email="maintainers@contouring-ros.org",
    description="Multi-axis contouring control of CNC feed drives as a graph of rclpy nodes",
    license="Apache-2.0",
    entry_points={
        # contouring_ros.nodes.scripts: each imports its node when it runs (one line, not a traceback, where
        # that import fails with a ContouringError, e.g. an rclpy lacking the internals the nodes use)
        "console_scripts": [f"{node} = {package_name}.nodes.scripts:{node}" for node in NODES]
        + [f"contouring-ros = {package_name}.cli:main"],
    },
)
