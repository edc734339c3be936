"""Wall-clock seconds of each stage of one ``vlp-plan`` run (``--timings``), and progress on a terminal."""

from __future__ import annotations

import time
from collections.abc import Callable


class Timings:
    """Wall-clock seconds of each stage of one run, in order (``vlp-plan --timings``).

    :meth:`stage` ends the running stage and starts the next, announcing it through ``show`` (progress on a
    terminal); a stage met twice adds up; :meth:`stop` ends the last.
    """

    def __init__(self, show: Callable[[str], None] | None = None):
        self.show = show
        self.seconds: dict[str, float] = {}
        self._running: tuple[str, float] | None = None

    def stage(self, name: str, detail: str = "") -> None:
        self.stop()
        if self.show:
            self.show(f"{name}: {detail}" if detail else name)
        self._running = (name, time.perf_counter())

    def stop(self) -> None:
        if self._running:
            name, t0 = self._running
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0
            self._running = None
