"""Full ``ros2msg`` schema text for MCAP, built the way rosbag2 Jazzy builds it.

The text is the root ``.msg`` file verbatim, then every dependency once, depth-first, each
dependency set visited in sorted order, each preceded by a line of 80 ``=`` and a line
``MSG: pkg/Type`` (rosbag2_storage_mcap ``MessageDefinitionCache::get_full_text``). The
``.msg`` files are read from the ROS packages' ``share/<pkg>/msg`` folders, found through
``AMENT_PREFIX_PATH`` and then the Python environment's prefix (where the PyPI wheels put them).
"""

from __future__ import annotations

import functools
import os
import re
import sys
from pathlib import Path

SEPARATOR = "=" * 80
_TYPE_NAME = re.compile(r"([a-zA-Z][a-zA-Z0-9_]*)/(?:msg/)?([a-zA-Z][a-zA-Z0-9_]*)")
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset(
    {
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
    }
)


def split_type_name(type_name: str) -> tuple[str, str]:
    """``"pkg/msg/Type"`` or ``"pkg/Type"`` → ``("pkg", "Type")``; ValueError otherwise."""
    match = _TYPE_NAME.fullmatch(type_name)
    if match is None:
        raise ValueError(f"type name {type_name!r} is not pkg/msg/Type")
    return match.group(1), match.group(2)


def share_roots() -> list[Path]:
    """Prefixes searched for ``share/<pkg>/msg``: AMENT_PREFIX_PATH, then sys.prefix."""
    roots = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    roots.append(Path(sys.prefix))
    return roots


@functools.cache
def msg_file_text(package: str, name: str) -> str:
    """The verbatim text of ``share/<package>/msg/<name>.msg``."""
    for root in share_roots():
        path = root / "share" / package / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_text(encoding="utf-8")
    raise FileNotFoundError(f"no {package}/msg/{name}.msg under {[str(r) for r in share_roots()]}")


def msg_dependencies(text: str, package: str) -> list[str]:
    """Sorted ``pkg/Type`` names a .msg text refers to (rosbag2's regex, same package default)."""
    deps: set[str] = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        deps.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(deps)


@functools.cache
def full_schema_text(type_name: str) -> str:
    """The ``ros2msg`` schema text for ``type_name`` (``pkg/msg/Type``)."""
    seen: set[str] = set()

    def expand(package: str, name: str, depth: int) -> str:
        if depth <= 0:
            raise ValueError(f"message definition of {type_name} nests too deeply")
        text = msg_file_text(package, name)
        out = text
        for dep in msg_dependencies(text, package):
            if dep in seen:
                continue
            seen.add(dep)
            dep_pkg, dep_name = split_type_name(dep)
            out += f"\n{SEPARATOR}\nMSG: {dep_pkg}/{dep_name}\n"
            out += expand(dep_pkg, dep_name, depth - 1)
        return out

    package, name = split_type_name(type_name)
    return expand(package, name, 50)
