"""ament_python package; also installable with plain `pip install -e .`."""
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "rearrangement_planner"
HERE = Path(__file__).parent


def tree(folder: str) -> list[tuple[str, list[str]]]:
    """data_files entries installing every file under `folder` into share/<package>/<folder>."""
    entries: dict[str, list[str]] = {}
    for path in sorted((HERE / folder).rglob("*")):
        if path.is_file():
            rel = path.relative_to(HERE)
            entries.setdefault(f"share/{PACKAGE}/{rel.parent}", []).append(str(rel))
    return sorted(entries.items())


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        *tree("config"),
        *tree("launch"),
        *tree("bags"),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="rearrangement_planner maintainers",
    maintainer_email="maintainers@example.org",
    description="Nonprehensile whole-arm rearrangement planning (PC-RRT) for ROS 2",
    license="Apache-2.0",
    python_requires=">=3.11",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            f"planner_node = {PACKAGE}.ros.node:main",
            f"world_sim = {PACKAGE}.ros.sim.world_sim:main",
            f"rearrangement-plan = {PACKAGE}.tools.cli:main",
            f"rearrangement-bench = {PACKAGE}.tools.bench.command:main",
            f"rearrangement-train = {PACKAGE}.tools.training.command:main",
            f"rearrangement-robot = {PACKAGE}.tools.robot_fit:main",
        ],
    },
)
