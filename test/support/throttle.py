"""Starve a node process the way a loaded machine does: SIGSTOP, and run it in short slices."""

from __future__ import annotations

import os
import signal
import threading
import time


class Throttle(threading.Thread):
    """Starve a process: SIGSTOP it, and let it run ``on`` s in every ``period`` s.

    Its DDS threads still get to receive and acknowledge (unlike a process stopped for good,
    whose unacknowledged samples are lost when the plant exits), while its callbacks fall
    behind, as on a machine whose CPU is taken by other jobs. Start it with ``start()``; stop
    it with :meth:`release`.
    """

    def __init__(self, pid: int, on: float = 0.005, period: float = 0.25) -> None:
        super().__init__(daemon=True)
        self.pid, self.on, self.period = pid, on, period
        self._done = threading.Event()

    def run(self) -> None:
        while not self._done.is_set():
            os.kill(self.pid, signal.SIGSTOP)
            if self._done.wait(self.period - self.on):
                break
            os.kill(self.pid, signal.SIGCONT)
            time.sleep(self.on)
        os.kill(self.pid, signal.SIGCONT)

    def release(self) -> None:
        """Let the process run freely again."""
        self._done.set()
        self.join()
        os.kill(self.pid, signal.SIGCONT)
