"""ament_python package of the adm_sim sources (``src/adm_sim``, linked here as ``adm_sim/``).

Built with ``colcon build`` (see docs/ros.md, "Building the ROS 2 packages with colcon"): installs
the Python package, the nodes as executables in ``lib/adm_sim`` (``ros2 run adm_sim bridge_node``),
and the params files and the DDS profile in ``share/adm_sim/{params,dds}``.
"""

from glob import glob

import xml.etree.ElementTree as ET
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "adm_sim"

#: the version stated once in package.xml (the release part of ``adm_sim.__version__``; tested)
VERSION = ET.parse(Path(__file__).resolve().parent / "package.xml").findtext("version")

setup(
    name=PACKAGE,
    version=VERSION,
    packages=find_packages(include=[PACKAGE, f"{PACKAGE}.*"]),
    package_data={PACKAGE: ["data/trains/*.toml", "data/examples/*.toml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/params", sorted(glob("params/*.yaml"))),
        (f"share/{PACKAGE}/dds", sorted(glob("dds/*.xml"))),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs test/ with pytest
    zip_safe=False,
    maintainer="adm-sim developers",
    maintainer_email="adm-sim@example.org",
    description="Railway-bridge dynamics (MLM, DIM): numerical core, bridge/train/driver nodes",
    license="MIT",
    entry_points={"console_scripts": [
        "bridge_node = adm_sim.nodes.bridge_node:main",
        "train_node = adm_sim.nodes.train_node:main",
        "driver = adm_sim.nodes.driver:main",
    ]},
)
