"""Reading the files a user hands us (scenes, robot configs, URDFs) without trusting them: one
path for the CLI, the node, the benchmark and the bags.

- `read_text(path, what)`: a regular file (not a directory, FIFO or device, which could block
  forever), at most `MAX_FILE_BYTES`, UTF-8; any problem is one `RearrangementError` line that
  names the file and what is wrong.
- `parse_yaml(text, what)`: YAML through libyaml when available (`CSafeLoader`, ~10x the pure
  Python parser), with the node graph checked before any Python object is built: no aliases
  (`*name`: a few hundred bytes of nested aliases expand to gigabytes), nesting at most
  `MAX_DEPTH` deep, at most `MAX_NODES` nodes.
- `quote(value)`: a value as it may appear in an error message, cut to `MAX_QUOTE` characters.
"""

from __future__ import annotations

import os
import reprlib
import stat
import sys
import sysconfig
from pathlib import Path
from typing import Any

import yaml

from rearrangement_planner.model.errors import RearrangementError

MAX_FILE_BYTES = 1 << 20
"""Largest scene, robot config or URDF read, bytes (the shipped ones are < 40 KiB)."""
MAX_DEPTH = 20
"""Deepest nesting of YAML collections accepted (a scene needs 4)."""
MAX_NODES = 200_000
"""Most YAML nodes in one file."""
MAX_QUOTE = 80
"""Longest quotation of a value in an error message, characters."""

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = MAX_QUOTE
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = 6
_REPR.maxlevel = 3


class FileProblem(RearrangementError):
    """A file that cannot be read or parsed; the message names the file and the problem."""


def quote(value: Any) -> str:
    """repr(value), bounded: long strings, deep or long collections and huge numbers are cut
    (a message never echoes a whole file or a 300-digit number)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**30:
        return f"an integer of {len(str(abs(value)))} digits"
    text = _REPR.repr(value)
    return text if len(text) <= MAX_QUOTE else text[:MAX_QUOTE - 3] + "..."


def read_text(path: str | os.PathLike[str], what: str) -> str:
    """The UTF-8 text of the regular file `path`; FileProblem naming `what` otherwise."""
    name = _shown(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise FileProblem(f"{what} {name} does not exist") from None
    except (OSError, ValueError) as exc:
        raise FileProblem(f"{what} {name}: cannot read it ({_reason(exc)})") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a directory" if stat.S_ISDIR(info.st_mode) else "not a regular file"
        raise FileProblem(f"{what} {name} is {kind}; give a {what} file")
    if info.st_size > MAX_FILE_BYTES:
        raise FileProblem(f"{what} {name} is {info.st_size:,} bytes; at most "
                          f"{MAX_FILE_BYTES:,} are read")
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise FileProblem(f"{what} {name}: cannot read it ({_reason(exc)})") from None
    if len(data) > MAX_FILE_BYTES:
        raise FileProblem(f"{what} {name} is over {MAX_FILE_BYTES:,} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise FileProblem(f"{what} {name} is not UTF-8 text (byte 0x{data[exc.start]:02x} on "
                          f"line {line})") from None


def parse_yaml(text: str, what: str) -> Any:
    """The YAML document `text` as Python data; FileProblem (naming `what`) for invalid YAML,
    aliases, nesting deeper than MAX_DEPTH or more than MAX_NODES nodes."""
    loader = _LOADER(text)
    try:
        try:
            node = loader.get_single_node()
        except yaml.YAMLError as exc:
            raise FileProblem(f"{what} is not valid YAML{_where(exc)}: "
                              f"{getattr(exc, 'problem', None) or quote(str(exc))}") from None
        if node is None:
            return None
        _check_graph(node, what)
        return loader.construct_document(node)
    except yaml.YAMLError as exc:     # a constructor error (e.g. an unknown tag)
        raise FileProblem(f"{what}: {getattr(exc, 'problem', None) or quote(str(exc))}"
                          f"{_where(exc)}") from None
    finally:
        loader.dispose()


def load_yaml(path: str | os.PathLike[str], what: str) -> Any:
    """`parse_yaml(read_text(path))`, the file named in every problem."""
    return parse_yaml(read_text(path, what), f"{what} {_shown(path)}")


def _check_graph(root: yaml.Node, what: str) -> None:
    """No node reached twice (an alias), depth <= MAX_DEPTH, count <= MAX_NODES; iterative,
    so a deep document cannot exhaust the Python stack."""
    seen: set[int] = set()
    stack: list[tuple[yaml.Node, int]] = [(root, 1)]
    while stack:
        node, depth = stack.pop()
        if id(node) in seen:
            raise FileProblem(f"{what} uses a YAML alias ({_mark(node)}); aliases are not "
                              f"accepted: write the values out")
        seen.add(id(node))
        if len(seen) > MAX_NODES:
            raise FileProblem(f"{what} has more than {MAX_NODES:,} YAML nodes")
        if depth > MAX_DEPTH:
            raise FileProblem(f"{what} nests collections more than {MAX_DEPTH} deep "
                              f"({_mark(node)})")
        if isinstance(node, yaml.SequenceNode):
            stack.extend((child, depth + 1) for child in node.value)
        elif isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                stack.extend(((key, depth + 1), (value, depth + 1)))


def _mark(node: yaml.Node) -> str:
    mark = node.start_mark
    return f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "?"


def _where(exc: yaml.YAMLError) -> str:
    mark = getattr(exc, "problem_mark", None)
    return f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""


def _shown(path: str | os.PathLike[str]) -> str:
    text = os.fspath(path)
    return text if len(text) <= MAX_QUOTE else f"{text[:40]}...{text[-30:]}"


def _reason(exc: BaseException) -> str:
    return getattr(exc, "strerror", None) or type(exc).__name__


def is_file(path: str | os.PathLike[str]) -> bool:
    """Path(path).is_file() that answers False, not an exception, for a name the OS refuses
    (too long, a NUL byte)."""
    try:
        return Path(path).is_file()
    except (OSError, ValueError):
        return False


def package_search_dirs() -> list[Path]:
    """Folders that hold ROS-style packages (`share/<package>`): each AMENT_PREFIX_PATH prefix's
    `share`, then the Python environment's (`sys.prefix/share`) and the cmeel prefix's that
    PyPI wheels such as example-robot-data install into."""
    prefixes = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(Path(sys.prefix))
    site = Path(sysconfig.get_paths()["purelib"])
    prefixes.append(site / "cmeel.prefix")
    return [p / "share" for p in prefixes if (p / "share").is_dir()]


def resolve_uri(uri: str | os.PathLike[str]) -> Path:
    """A file path from a path or a `package://PACKAGE/REST` URI (found under
    `package_search_dirs`). FileProblem names the package when no folder holds it."""
    text = str(uri)
    if not text.startswith("package://"):
        return Path(text)
    package, _, rest = text[len("package://"):].partition("/")
    dirs = package_search_dirs()
    for share in dirs:
        if (share / package).is_dir():
            return share / package / rest
    where = ", ".join(map(str, dirs)) or "any install prefix"
    raise FileProblem(f"{text}: no package {package!r} in {where}; install it or add its "
                      f"prefix to AMENT_PREFIX_PATH")
