"""Package layout that pyproject.toml alone cannot say: the robots in ``configs/robots`` (one
folder per robot: config, README, licence) ship inside the wheel as ``robot_retarget/robots``,
so an installed package finds its robots without the repository (the files it takes are listed
under ``package-data`` in pyproject.toml)."""

from setuptools import find_packages, setup

setup(
    packages=[
        *find_packages(include=["robot_retarget", "robot_retarget.*"]),
        "robot_retarget.robots",
    ],
    package_dir={"robot_retarget.robots": "configs/robots"},
)
