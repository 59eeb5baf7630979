"""ament_python package tire_estimation: nodes, pure-Python core, simulator, bag tools."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "tire_estimation"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="tire_estimation maintainers",
    maintainer_email="maintainers@tire-estimation.invalid",
    description="Online tire radius and stiffness estimation and deflation detection.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "tire-estimation = tire_estimation.cli:main",
            "estimator_node = tire_estimation.nodes.estimator_node:main",
            "bag_player = tire_estimation.nodes.bag_player:main",
            "detector_node = tire_estimation.nodes.detector_node:main",
        ],
    },
)
