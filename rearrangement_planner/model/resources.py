"""Where the package's shipped data (config/: robots, scenes, parameters) lives.

A source checkout keeps it beside the package; an installed package (pip or colcon) has it in
``<prefix>/share/rearrangement_planner``.
"""

import os
import sys
from functools import cache
from pathlib import Path

PACKAGE = "rearrangement_planner"
NODE_NAME = PACKAGE
"""The planner node's name (docs/design.md): its topics and services are /rearrangement_planner/*;
its executable is `planner_node`."""


@cache
def share_dir() -> Path:
    """The folder holding `config/` (and `launch/`): env override, checkout, then install prefix."""
    candidates = []
    if os.environ.get("REARRANGEMENT_PLANNER_SHARE"):
        candidates.append(Path(os.environ["REARRANGEMENT_PLANNER_SHARE"]))
    candidates.append(Path(__file__).resolve().parents[2])
    candidates.append(Path(sys.prefix) / "share" / PACKAGE)
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            candidates.append(Path(prefix) / "share" / PACKAGE)
    for candidate in candidates:
        if (candidate / "config" / "robots").is_dir():
            return candidate
    raise FileNotFoundError(
        f"cannot find the {PACKAGE} config folder; looked in: "
        + ", ".join(str(c) for c in candidates)
    )


def config_dir() -> Path:
    return share_dir() / "config"


def robots_dir() -> Path:
    return config_dir() / "robots"


def scenes_dir() -> Path:
    return config_dir() / "scenes"


def default_scene_file() -> Path:
    """The default scene (`make demo`, the benchmark scenes' table and start)."""
    return scenes_dir() / "default.yaml"


@cache
def _default_scene() -> dict:
    import yaml

    return yaml.safe_load(default_scene_file().read_text())


def default_robot() -> str:
    """The name of the default scene's robot: the robot every tool uses when none is named."""
    return str(_default_scene()["robot"])


def default_start() -> list[float]:
    """The default scene's start configuration (every benchmark scene starts there)."""
    return [float(v) for v in _default_scene()["start_configuration"]]
