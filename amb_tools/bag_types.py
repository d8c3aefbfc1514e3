"""Message types for rosbag2 files of this project, for the ``rosbags`` library.

Bags are written and read without a ROS install (``rosbags``), so the ``amb_msgs`` types must be
registered with a type store from their ``.msg`` definitions. The definitions are read from the
colcon install space (``share/amb_msgs/msg``) when ``amb_msgs`` is built, else from the source
tree beside this package, so that the same files define the types for rclpy and for the bags.
"""

from __future__ import annotations

import functools
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

PACKAGE = "amb_msgs"
_SOURCE_MSG_DIR = Path(__file__).resolve().parent.parent / "amb_msgs" / "msg"


class MessageDefinitionsNotFoundError(FileNotFoundError):
    """The ``amb_msgs`` ``.msg`` files are neither installed nor in the source tree."""


def msg_dir() -> Path:
    """Return the folder holding the ``amb_msgs`` ``.msg`` definitions.

    Returns
    -------
    pathlib.Path
        ``<install>/share/amb_msgs/msg`` if the package is on the ament index, else the source
        folder ``amb_msgs/msg`` of this checkout.

    Raises
    ------
    MessageDefinitionsNotFoundError
        If neither exists.
    """
    try:
        from ament_index_python.packages import get_package_share_directory

        installed = Path(get_package_share_directory(PACKAGE)) / "msg"
        if installed.is_dir():
            return installed
    except (ImportError, LookupError, ValueError):
        pass
    if _SOURCE_MSG_DIR.is_dir():
        return _SOURCE_MSG_DIR
    raise MessageDefinitionsNotFoundError(
        f"no {PACKAGE} message definitions: not on the ament index and not at {_SOURCE_MSG_DIR}; "
        "run tools/bootstrap.sh (or source install/setup.bash)"
    )


@functools.cache
def typestore() -> Typestore:
    """Return a ROS 2 Jazzy type store with every ``amb_msgs`` message registered.

    Returns
    -------
    rosbags.typesys.store.Typestore
        Shared, cached instance; do not register further types into it.
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict = {}
    for path in sorted(msg_dir().glob("*.msg")):
        types.update(get_types_from_msg(path.read_text(), f"{PACKAGE}/msg/{path.stem}"))
    store.register(types)
    return store


def ros_type_name(msgtype: str) -> str:
    """Normalise ``pkg/Name`` or ``pkg/msg/Name`` to the ``pkg/msg/Name`` form bags use.

    Parameters
    ----------
    msgtype : str
        Message type name.

    Returns
    -------
    str
        ``pkg/msg/Name``.

    Raises
    ------
    ValueError
        If the name has neither form.
    """
    parts = msgtype.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    if len(parts) == 3 and parts[1] == "msg":
        return msgtype
    raise ValueError(f"message type {msgtype!r} is not of the form 'pkg/msg/Name' or 'pkg/Name'")
