"""With --baud auto on a port: a sink that says once, on stderr, when the chosen rate stops giving valid frames."""

from __future__ import annotations

import sys

from ..decode.autobaud import BaudWatch
from ..decode.decoder import Step
from .pipeline import Sink


class BaudWatchWarning(Sink):
    """With ``--baud auto`` on a port: says once, on stderr, when the chosen rate stops giving valid
    frames (a baud change written to the servos mid-session is common during setup)."""

    def __init__(self, port: str, baud: int) -> None:
        self.port = port
        self.watch = BaudWatch(baud)
        self.said = False

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        self.watch.chunk(data, t)
        self._say()

    def batch(self, step: Step) -> None:
        self.watch.batch(step)
        self._say()

    def _say(self) -> None:
        if self.watch.rescan_due and not self.said:
            self.said = True
            print(f"rs30x-sniff: warning: {self.port}: {self.watch.reason} (run again with --baud auto)",
                  file=sys.stderr)
