"""
The Fast DDS profile the nodes run with: reliable writers that repair a stalled reader in 20 ms.

A reliable Fast DDS writer resends the messages a reader lacks when the reader answers one of
its heartbeats, every 3 s by default. A reader stopped or descheduled longer than its
shared-memory port holds (512 messages) loses the rest of the stall's messages in the
transport, and the reliable reader holds every later one back until they are resent: in
``realtime`` the chain then stays behind the plant by up to a heartbeat period however fast it
drops what is old (``amb_tools.backlog``; ``test/reliability/test_overload_catch_up.py``,
``docs/history.md``, "Repairs after a stall").
``config/fastdds_profile.xml`` makes the period 20 ms for every writer of the process; the
topics' QoS are the nodes' own as before.

The profile is a process's environment (``FASTRTPS_DEFAULT_PROFILES_FILE``, read when the
first DDS participant is made), so :func:`use_project_profile` is called before ``rclpy.init``
by every node executable (:func:`amb_tools.node_main.run_nodes`). A profile of the user's own
(either variable set) is left alone: it should set the writers' heartbeat as this one does.
Another RMW than Fast DDS ignores the variable.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

from amb_common.paths import config_file

__all__ = ["PROFILE_VARIABLES", "project_profile", "use_project_profile"]

#: The variables Fast DDS reads a default profile file from (2.x, and 3.x's new name).
PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def project_profile() -> Path:
    """The project's Fast DDS profile file (installed copy, else the source tree's)."""
    return config_file("fastdds_profile.xml")


def use_project_profile(environ: MutableMapping[str, str] | None = None) -> Path | None:
    """
    Point Fast DDS at the project's profile unless a profile file is already chosen.

    Parameters
    ----------
    environ : mapping, optional
        The environment to set (default: ``os.environ``, this process's, before ``rclpy.init``).

    Returns
    -------
    pathlib.Path or None
        The profile now in effect: the project's, or the user's (either variable); None if the
        project's file is missing (a broken install: Fast DDS's defaults then apply).
    """
    env = os.environ if environ is None else environ
    for name in PROFILE_VARIABLES:
        if env.get(name):
            return Path(env[name])
    path = project_profile()
    if not path.is_file():
        return None
    env[PROFILE_VARIABLES[0]] = str(path)
    return path
