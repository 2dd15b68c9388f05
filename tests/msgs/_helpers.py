"""Shared helpers for the localpbo_msgs_py tests (no ROS graph is created here)."""

from __future__ import annotations

import array
from typing import Any

import numpy as np


def plain(obj: Any, ref: Any) -> Any:
    """A comparable plain-Python view of ``obj``, walked along the rclpy message ``ref``.

    ``ref`` (an rclpy message) supplies the field names, so messages decoded by other readers
    (mcap_ros2 dynamic classes, rosbags dataclasses) map to the same structure. Byte fields
    become ints, numeric arrays become lists of Python scalars.
    """
    if hasattr(ref, "get_fields_and_field_types"):
        fields = ref.get_fields_and_field_types()
        return {k: plain(getattr(obj, k), getattr(ref, k)) for k in fields}
    if isinstance(ref, list | tuple | array.array | np.ndarray):
        items = list(obj)
        refs = list(ref)
        assert len(items) == len(refs), (items, refs)
        return [plain(o, r) for o, r in zip(items, refs, strict=True)]
    if isinstance(obj, bytes | bytearray) and len(obj) == 1:
        return obj[0]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj
