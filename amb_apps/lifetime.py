"""How long a run's processes live: children tied to their parent, the parent's stop signals.

``amb-run`` starts every node as a child process and stops them when the run ends, is
interrupted or is terminated. A parent that dies without its cleanup (SIGKILL, the
out-of-memory killer, a test harness's timeout) used to leave the whole node set running: the
plant on through its scenario, the controller commanding, the recorder writing, all on the
run's ROS domain where the next run's nodes meet them (a killed test's nodes once crossed five
later tests). On Linux the kernel can send a child a signal when the thread that forked it
exits (``prctl(PR_SET_PDEATHSIG)``, kept across ``execve`` of a non-set-user-ID program):
:func:`die_with_parent` sets it between the fork and the exec. The signal is SIGINT, the one
``amb-run`` stops its nodes with, so a node left alone shuts down as in a normal stop (the
recorder closes its bag).

The signal follows the forking *thread*: start children from a thread that lives as long as
they should (``amb-run`` and the test harness use the main thread).

The parent's side (:class:`StopSignals`): SIGTERM (what ``kill``, ``timeout``, systemd and
container runtimes send) and SIGHUP (the terminal closed) ended ``amb-run`` at once, by
Python's default, without the cleanup that stops the nodes and lets the recorder write the
last messages; under :class:`StopSignals` they stop the run as Ctrl-C does, at the next
point where the run checks for them.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
from collections.abc import Callable

#: ``PR_SET_PDEATHSIG`` of ``<linux/prctl.h>``.
PR_SET_PDEATHSIG = 1
#: Exit status of a child whose parent was gone before the signal was armed.
ORPHANED_EXIT = 70

_libc = ctypes.CDLL(None, use_errno=True) if sys.platform.startswith("linux") else None


def die_with_parent(
    sig: int = signal.SIGINT, then: Callable[[], None] | None = None
) -> Callable[[], None] | None:
    """A ``preexec_fn`` for :class:`subprocess.Popen` that ties the child to this process.

    Parameters
    ----------
    sig : int
        Signal the child gets when the forking thread of this process exits.
    then : callable, optional
        Further set-up to run in the child after it (e.g. its scheduling).

    Returns
    -------
    callable or None
        The function to pass as ``preexec_fn``; ``then`` itself where the platform has no
        ``prctl`` (the child is then not tied).

    Notes
    -----
    A parent that died between the fork and the ``prctl`` call would never send the signal;
    the child checks that its parent is still the process that forked it and exits with
    :data:`ORPHANED_EXIT` otherwise.
    """
    if _libc is None:
        return then
    parent = os.getpid()
    prctl = _libc.prctl  # resolved here, in the parent: the child only calls it

    def tie() -> None:
        if prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
        if os.getppid() != parent:
            os._exit(ORPHANED_EXIT)
        if then is not None:
            then()

    return tie


class RunStopped(Exception):  # noqa: N818 (a request, not an error)
    """The run was asked to stop by a signal (:class:`StopSignals`)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


#: Signals :class:`StopSignals` turns into :class:`RunStopped` (SIGINT stays Python's
#: KeyboardInterrupt).
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


class StopSignals:
    """SIGTERM and SIGHUP recorded as a stop request, raised where the caller checks for it.

    The handler only records the signal. An exception raised *from* a handler comes out of
    whatever the main thread was running when the signal arrived; inside rclpy's C++ (an
    executor's ``spin_once`` taking a message) pybind11 turned it into a ``RuntimeError``
    ("Unable to convert call argument '0'"), ``amb-run`` ended with status 1 and a traceback
    instead of its stop. The caller's wait loops call :meth:`check` between their spins
    (every 50 ms in ``amb-run``), in Python, where :class:`RunStopped` stays itself.

    Off the main thread (where Python cannot set handlers) nothing is caught.

    Parameters
    ----------
    notice : callable
        Told about a signal that comes after the first (the cleanup is under way and should
        not be cut short).
    """

    def __init__(self, notice: Callable[[str], None] = print) -> None:
        self.signum: int | None = None
        self._raised = False
        self._notice = notice
        self._previous: dict[int, object] = {}
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._handler) for s in STOP_SIGNALS}

    def _handler(self, signum: int, _frame) -> None:
        if self.signum is not None:
            self._notice(f"{signal.Signals(signum).name} again: already stopping")
            return
        self.signum = signum

    def check(self) -> None:
        """Raise :class:`RunStopped` for the first recorded signal, once; else do nothing."""
        if self.signum is not None and not self._raised:
            self._raised = True
            raise RunStopped(self.signum)

    def restore(self) -> None:
        """Put the previous handlers back (call it when the cleanup is done)."""
        for s, h in self._previous.items():
            signal.signal(s, h)
        self._previous = {}
