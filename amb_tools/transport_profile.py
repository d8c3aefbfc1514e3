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

Off shared memory (``AMB_TRANSPORT=udp`` in a process's environment; ``amb-run --udp NODE``).
Fast DDS delivers between processes of one machine through shared-memory ports. A reader's
listener takes its port's process-shared mutex for every message it takes; stopped or
descheduled while it holds it, it holds every writer that pushes to that port, in every process
(``docs/history.md``, "A stopped reader that blocks its writers": the plant's ``publish``
found waiting there, the mutex's owner the stopped recorder's listener thread). A process
whose participant has no shared-memory transport is reached over UDP on 127.0.0.1 and shares
no lock with its writers. Two ways, after what the RMW does with the discovery range:

* ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (``tools/env.sh``'s; or, unset, the deprecated
  ``ROS_LOCALHOST_ONLY=1``, which is then removed): rmw_fastrtps 8.4 then
  replaces the participant's transports with its own (UDPv4 on 127.0.0.1 and shared memory,
  the built-in ones off), so neither ``FASTDDS_BUILTIN_TRANSPORTS`` nor a profile's transports
  reach the participant (tried: a process's threads still include ``dds.shm``). The process
  instead gets the profile's participant ``amb_loopback_udp`` as its default (a copy of the
  profile with that participant marked default, :func:`loopback_profile`) and the range
  ``SYSTEM_DEFAULT``, with which the RMW leaves the transports and locators to the profile:
  UDPv4 on 127.0.0.1 only, discovery unicast to 127.0.0.1 only, as the localhost range's.
  ``ROS_STATIC_PEERS``, which the RMW adds only for the localhost and subnet ranges, is then
  not applied to that process (peers on other machines are not reachable over 127.0.0.1).
* Any other range (``SUBNET``, ``SYSTEM_DEFAULT``): the RMW leaves the transports alone, and
  ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4`` takes the shared memory away.

A user's own profile file is left alone with ``AMB_TRANSPORT=udp`` too (:class:`TransportError`
says so): the transport is then the user's to set in it.
"""

from __future__ import annotations

import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import MutableMapping
from pathlib import Path

from amb_common.paths import config_file

__all__ = [
    "LOOPBACK_PARTICIPANT",
    "PROFILE_VARIABLES",
    "TRANSPORT_VARIABLE",
    "TransportError",
    "loopback_profile",
    "project_profile",
    "transport_of",
    "use_project_profile",
]

#: The variables Fast DDS reads a default profile file from (2.x, and 3.x's new name).
PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
#: A process's transport: ``shm`` (unset: Fast DDS's shared memory and UDP) or ``udp``.
TRANSPORT_VARIABLE = "AMB_TRANSPORT"
TRANSPORTS = ("shm", "udp")
#: The profile file's participant profile of a process off shared memory.
LOOPBACK_PARTICIPANT = "amb_loopback_udp"
RANGE_VARIABLE = "ROS_AUTOMATIC_DISCOVERY_RANGE"
LOCALHOST_ONLY_VARIABLE = "ROS_LOCALHOST_ONLY"
_NAMESPACE = "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"


class TransportError(ValueError):
    """``AMB_TRANSPORT`` has a value other than ``shm`` or ``udp``, or cannot be applied."""


def transport_of(environ: MutableMapping[str, str]) -> str:
    """The transport ``environ`` asks for: ``shm`` (also when unset) or ``udp``.

    Raises
    ------
    TransportError
        Any other value, named with the ones allowed.
    """
    value = environ.get(TRANSPORT_VARIABLE, "").strip().lower() or "shm"
    if value not in TRANSPORTS:
        raise TransportError(
            f"{TRANSPORT_VARIABLE}={environ[TRANSPORT_VARIABLE]!r}: expected one of {TRANSPORTS}"
        )
    return value


def project_profile() -> Path:
    """The project's Fast DDS profile file (installed copy, else the source tree's)."""
    return config_file("fastdds_profile.xml")


def loopback_profile(profile: Path, folder: Path | None = None) -> Path:
    """
    A copy of ``profile`` whose participant :data:`LOOPBACK_PARTICIPANT` is the default.

    Parameters
    ----------
    profile : pathlib.Path
        The project's profile file (it holds that participant profile, not as the default).
    folder : pathlib.Path, optional
        Where the copy is written (default: a folder of this user's in the system's temporary
        directory). The copy is replaced atomically: processes starting together may write it.

    Returns
    -------
    pathlib.Path
        The copy.

    Raises
    ------
    TransportError
        ``profile`` has no participant profile of that name.
    """
    ET.register_namespace("", _NAMESPACE)
    tree = ET.parse(profile)
    found = [
        p for p in tree.getroot().iter(f"{{{_NAMESPACE}}}participant")
        if p.get("profile_name") == LOOPBACK_PARTICIPANT
    ]  # fmt: skip
    if not found:
        raise TransportError(f"{profile} has no participant profile {LOOPBACK_PARTICIPANT!r}")
    found[0].set("is_default_profile", "true")
    if folder is None:
        folder = Path(tempfile.gettempdir()) / f"amb_wavelet_control-{os.getuid()}"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{profile.stem}_{LOOPBACK_PARTICIPANT}.xml"
    fd, scratch = tempfile.mkstemp(dir=folder, suffix=".xml")
    with os.fdopen(fd, "wb") as fh:
        tree.write(fh, encoding="UTF-8", xml_declaration=True)
    os.replace(scratch, path)
    return path


def use_project_profile(environ: MutableMapping[str, str] | None = None) -> Path | None:
    """
    Point Fast DDS at the project's profile unless a profile file is already chosen.

    With ``AMB_TRANSPORT=udp`` the process is also taken off shared memory (module notes): the
    profile is then :func:`loopback_profile`'s copy and the discovery range ``SYSTEM_DEFAULT``
    where it was ``LOCALHOST``, else ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``.

    Parameters
    ----------
    environ : mapping, optional
        The environment to set (default: ``os.environ``, this process's, before ``rclpy.init``).

    Returns
    -------
    pathlib.Path or None
        The profile now in effect: the project's (or its copy), or the user's (either
        variable); None if the project's file is missing (a broken install: Fast DDS's
        defaults then apply).

    Raises
    ------
    TransportError
        ``AMB_TRANSPORT`` is neither ``shm`` nor ``udp``; or it is ``udp`` where it cannot be
        applied: a profile file of the user's, or the project's file missing.
    """
    env = os.environ if environ is None else environ
    off_shm = transport_of(env) == "udp"
    for name in PROFILE_VARIABLES:
        if env.get(name):
            if off_shm:
                raise TransportError(
                    f"{TRANSPORT_VARIABLE}=udp with a profile file of your own ({name}="
                    f"{env[name]}): set the transport in that file, or unset one of the two"
                )
            return Path(env[name])
    path = project_profile()
    if not path.is_file():
        if off_shm:
            raise TransportError(f"{TRANSPORT_VARIABLE}=udp: the profile {path} is missing")
        return None
    if off_shm:
        scope = env.get(RANGE_VARIABLE, "").upper()
        if scope == "LOCALHOST" or (not scope and env.get(LOCALHOST_ONLY_VARIABLE) == "1"):
            path = loopback_profile(path)
            env[RANGE_VARIABLE] = "SYSTEM_DEFAULT"
            env.pop(LOCALHOST_ONLY_VARIABLE, None)  # the deprecated spelling of LOCALHOST
        else:
            env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
    env[PROFILE_VARIABLES[0]] = str(path)
    return path
