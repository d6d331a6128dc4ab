"""ament_python package of the adm_calib sources (``src/adm_calib``, linked here as ``adm_calib/``).

Built with ``colcon build`` together with ``adm_sim``: installs the Python package and the
calibration node as ``lib/adm_calib/calibration_node`` (``ros2 run adm_calib calibration_node``).
"""

import xml.etree.ElementTree as ET
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "adm_calib"

#: the version stated once in package.xml (the release part of ``adm_sim.__version__``; tested)
VERSION = ET.parse(Path(__file__).resolve().parent / "package.xml").findtext("version")

setup(
    name=PACKAGE,
    version=VERSION,
    packages=find_packages(include=[PACKAGE, f"{PACKAGE}.*"]),
    package_data={PACKAGE: ["data/*.toml", "data/*.csv"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs test/ with pytest
    zip_safe=False,
    maintainer="adm-sim developers",
    maintainer_email="adm-sim@example.org",
    description="Additional-damping calibration and the calibration node",
    license="MIT",
    entry_points={"console_scripts": [
        "calibration_node = adm_calib.nodes.calibration_node:main",
    ]},
)
