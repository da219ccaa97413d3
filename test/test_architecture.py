"""The folder tree is the architecture (docs/design.md "Layering"): dependencies point one way,
model -> physics -> world3d -> planning -> execution -> io -> tools, with the ROS layer (`ros/`,
`msg_adapters/`) on top; nothing outside `ros/` and `msg_adapters/` imports rclpy, ROS message
packages or msg_adapters; no import cycles (counting imports inside functions and under
TYPE_CHECKING); no private names imported across modules."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "rearrangement_planner"
LAYERS = ["model", "physics", "world3d", "planning", "execution", "io", "tools", "ros"]
"""A module may import from its own layer and the layers before it."""
ROS_MODULES = ("rclpy", "builtin_interfaces", "geometry_msgs", "sensor_msgs", "std_msgs",
               "std_srvs", "trajectory_msgs", "visualization_msgs", "diagnostic_msgs",
               "rcl_interfaces", "msg_adapters", "rearrangement_interfaces", "action_msgs")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> list[tuple[str, list[str], int]]:
    """Every import in the file, wherever it stands: (module, imported names, line)."""
    found = []
    package = _module_name(path).rsplit(".", 1)[0] if path.name != "__init__.py" \
        else _module_name(path)
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [(alias.name, [], node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([module] if module else []))
            found.append((module, [a.name for a in node.names], node.lineno))
    return found


def _sources() -> list[Path]:
    return sorted((ROOT / PACKAGE).rglob("*.py")) + sorted((ROOT / "msg_adapters").rglob("*.py"))


def _layer(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "msg_adapters":
        return "ros"
    return parts[1] if parts[0] == PACKAGE and len(parts) > 1 and parts[1] in LAYERS else None


def _internal_targets(module: str, names: list[str], known: set[str]) -> list[str]:
    """The package modules an import statement depends on."""
    targets = [module] if module in known else []
    targets += [f"{module}.{n}" for n in names if f"{module}.{n}" in known]
    return targets


def test_every_module_lives_in_a_layer():
    stray = [_module_name(p) for p in (ROOT / PACKAGE).glob("*.py") if p.name != "__init__.py"]
    assert stray == [], f"modules outside the subpackages {LAYERS}: {stray}"


@pytest.mark.parametrize("path", _sources(), ids=lambda p: _module_name(p))
def test_imports_point_down_the_layers(path: Path):
    known = {_module_name(p) for p in _sources()}
    me = _module_name(path)
    mine = LAYERS.index(_layer(me)) if _layer(me) else len(LAYERS)
    for module, names, line in _imports(path):
        root = module.split(".")[0]
        if _layer(me) != "ros":
            assert root not in ROS_MODULES, f"{me}:{line} imports {module}: only ros/ and " \
                                            f"msg_adapters/ may know ROS"
        for target in _internal_targets(module, names, known):
            layer = _layer(target)
            if layer is not None:
                assert LAYERS.index(layer) <= mine, f"{me}:{line} imports {target} ({layer}) " \
                                                    f"from below, in layer {_layer(me)}"
        if root in (PACKAGE, "msg_adapters") and module != me:
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            assert not private, f"{me}:{line} imports private {private} from {module}"


ROOMS = ["machinery", "planners", "requests"]
"""planning/'s rooms, in order: the search machinery the planners share, the planners, and the
pipeline around a search. A planning module may import from its own room and the rooms before
it (the package's __init__ re-exports from all three)."""


def _room(module: str) -> str | None:
    parts = module.split(".")
    return parts[2] if len(parts) > 3 and parts[1] == "planning" and parts[2] in ROOMS \
        else None


def test_every_planning_module_lives_in_a_room():
    stray = [_module_name(p) for p in (ROOT / PACKAGE / "planning").glob("*.py")
             if p.name != "__init__.py"]
    assert stray == [], f"planning modules outside the rooms {ROOMS}: {stray}"


@pytest.mark.parametrize("path", sorted((ROOT / PACKAGE / "planning").rglob("*.py")),
                         ids=lambda p: _module_name(p))
def test_planning_imports_point_down_the_rooms(path: Path):
    known = {_module_name(p) for p in _sources()}
    me = _module_name(path)
    if _room(me) is None:
        return                      # planning/__init__.py and the rooms' own __init__
    for module, names, line in _imports(path):
        for target in _internal_targets(module, names, known):
            room = _room(target)
            if room is not None:
                assert ROOMS.index(room) <= ROOMS.index(_room(me)), \
                    f"{me}:{line} imports {target} (room {room}) from room {_room(me)}"


def test_no_import_cycles():
    known = {_module_name(p) for p in _sources()}
    graph = {_module_name(p): set() for p in _sources()}
    for path in _sources():
        me = _module_name(path)
        for module, names, _ in _imports(path):
            for target in _internal_targets(module, names, known):
                # A package's __init__ re-exporting its own modules is not a dependency.
                if target != me and not (path.name == "__init__.py"
                                         and target.startswith(me + ".")):
                    graph[me].add(target)
    # Packages depend on what their __init__ imports; a module importing `pkg.mod` also
    # runs `pkg/__init__`, which is only a cycle when that __init__ imports back.
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycle = stack[stack.index(nxt):] + [nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node)


CORE_LAYERS = ("model", "physics", "world3d", "planning", "execution", "io")
"""Functions here read like the paper: at most 60 lines; elsewhere at most 80."""


@pytest.mark.parametrize("path", _sources(), ids=lambda p: _module_name(p))
def test_functions_and_classes_stay_small(path: Path):
    core = _layer(_module_name(path)) in CORE_LAYERS
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ClassDef):
            limit = 300
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            limit = 60 if core else 80
        else:
            continue
        length = (node.end_lineno or node.lineno) - node.lineno + 1
        assert length <= limit, f"{_module_name(path)}.{node.name} has {length} lines " \
                                f"(at most {limit})"


def test_nothing_in_the_core_names_a_particular_arm():
    """Robots come from config/ (a URDF and a robot config): no module of the package or the
    message adapters names the first shipped arm, not even in a comment."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    named = [f"{path.relative_to(root)}:{n}" for folder in ("rearrangement_planner",
                                                             "msg_adapters")
             for path in sorted((root / folder).rglob("*.py"))
             for n, line in enumerate(path.read_text().splitlines(), start=1)
             if re.search("panda|franka", line, re.IGNORECASE)]
    assert named == []
