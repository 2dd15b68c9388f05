"""Run a decoder body so that it returns a DecodeError instead of raising."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from localpbo_msgs_py._validate import wrong_type
from localpbo_msgs_py.errors import DecodeError, DecodeReason, FieldError

T = TypeVar("T")


def guarded(schema: str, body: Callable[[], T]) -> T | DecodeError:
    """Call ``body``; map ``FieldError`` (and any other exception) to a ``DecodeError``."""
    try:
        return body()
    except FieldError as exc:
        return DecodeError(schema, exc.field, exc.reason, exc.problem)
    except Exception as exc:  # a decoder must never raise into a ROS callback
        return DecodeError(
            schema,
            "message",
            DecodeReason.MALFORMED,
            f"undecodable ({type(exc).__name__}: {str(exc)[:200]})",
        )


def check_type(msg: object, cls: type, type_name: str) -> None:
    """Raise ``FieldError`` unless ``msg`` is an instance of the ROS class ``cls``."""
    if not isinstance(msg, cls):
        raise wrong_type("message", type_name, msg)
