"""Fill any ROS 2 message with random values, and compare messages field by field.

The filler walks the generated class's ``SLOT_TYPES`` (rosidl type definitions), so it covers
every field of every ``amb_msgs`` type, including nested messages and sequences, without a
hand-written list that could miss a field.
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np
from rosidl_parser.definition import (
    AbstractNestedType,
    Array,
    BasicType,
    BoundedString,
    NamespacedType,
    UnboundedString,
)

_INT_RANGES = {
    "int8": (-128, 127),
    "uint8": (0, 255),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}


def _basic(rng: np.random.Generator, typename: str) -> Any:
    if typename in _INT_RANGES:
        lo, hi = _INT_RANGES[typename]
        return int(rng.integers(lo, hi, endpoint=True, dtype=np.uint64 if lo == 0 else np.int64))
    if typename == "double":
        return float(rng.normal() * 10.0 ** rng.integers(-9, 4))
    if typename == "float":
        return float(np.float32(rng.normal()))
    if typename == "boolean":
        return bool(rng.integers(0, 2))
    if typename in ("octet", "char"):
        return bytes([int(rng.integers(0, 256))]) if typename == "octet" else "x"
    raise TypeError(f"no random value for basic type {typename}")


def _string(rng: np.random.Generator) -> str:
    return "".join(rng.choice(list("abcxyz_/019 äµ"), size=int(rng.integers(0, 12))))


def _class_of(t: NamespacedType) -> type:
    module = importlib.import_module(".".join(t.namespaces))
    return getattr(module, t.name)


def _value(rng: np.random.Generator, t: Any) -> Any:
    if isinstance(t, BasicType):
        return _basic(rng, t.typename)
    if isinstance(t, (UnboundedString, BoundedString)):
        return _string(rng)
    if isinstance(t, NamespacedType):
        return random_message(_class_of(t), rng)
    if isinstance(t, AbstractNestedType):
        n = t.size if isinstance(t, Array) else int(rng.integers(0, 6))
        values = [_value(rng, t.value_type) for _ in range(n)]
        if isinstance(t.value_type, BasicType) and t.value_type.typename in ("double", "float"):
            return np.array(values) if isinstance(t, Array) else values
        return values
    raise TypeError(f"no random value for field type {t!r}")


def random_message(cls: type, rng: np.random.Generator) -> Any:
    """Return an instance of message class ``cls`` with every field set at random."""
    msg = cls()
    fields = [s for s in cls.__slots__ if s != "_check_fields"]
    for slot, t in zip(fields, cls.SLOT_TYPES, strict=True):
        setattr(msg, slot[1:], _value(rng, t))
    return msg


def to_plain(msg: Any) -> Any:
    """Convert a message (rclpy or rosbags) to nested dicts/lists of plain Python values."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {f: to_plain(getattr(msg, f)) for f in msg.get_fields_and_field_types()}
    if hasattr(msg, "__dataclass_fields__"):
        fields = [
            name
            for name, f in msg.__dataclass_fields__.items()
            if name.islower() and not name.startswith("_") and f.metadata.get("message_field", True)
        ]  # a view's own additions (amb_tools.cdr) are not message fields
        return {f: to_plain(getattr(msg, f)) for f in fields}  # rosbags: constants are fields
    if isinstance(msg, np.ndarray):
        return [to_plain(v) for v in msg.tolist()]
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == "array":
        return [to_plain(v) for v in msg]
    if isinstance(msg, np.generic):
        return msg.item()
    return msg


def diff(a: Any, b: Any, path: str = "") -> list[str]:
    """Return the paths where two plain structures differ (empty if equal)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return [f"{path}: fields {sorted(a)} != {sorted(b)}"]
        return [d for k in a for d in diff(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: length {len(a)} != {len(b)}"]
        pairs = enumerate(zip(a, b, strict=True))
        return [d for i, (x, y) in pairs for d in diff(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]
