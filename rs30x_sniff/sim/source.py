"""The simulator as the monitor's source: a scenario run in this process, paced in real time."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator

from ..protocol.wire import byte_time
from ..sources.captures import CaptureError
from ..sources.feeds import Chunk, paced
from .scenarios import SCENARIOS, run

SIMULATE_SECONDS = 3600.0  # a simulated session runs for an hour of bus time unless the user quits


class SimulatorSource:
    """The built-in simulator running a scenario in this process, paced in real time (``speed`` x)."""

    kind = "simulator"
    live = True  # paced in real time, as a port
    streamed = False
    batched = False
    time_base = "capture"

    def __init__(self, scenario: str, baud: int, *, speed: float = 1.0, duration: float = SIMULATE_SECONDS,
                 seed: int = 0, clock: Callable[[], float] = time.monotonic) -> None:
        if scenario not in SCENARIOS:
            raise CaptureError(f"--simulate {scenario}: unknown scenario (known: {', '.join(SCENARIOS)})")
        self.name = scenario
        self.speed = speed
        self.byte_seconds = byte_time(baud)
        self.clock = clock
        try:
            self._it = run(scenario, baud=baud, seed=seed, duration=duration)
            # Its first chunk made now, so a scenario that cannot run fails before the screen starts.
            self._first = next(self._it, None)
        except ValueError as e:
            raise CaptureError(f"--simulate {scenario}: {e}") from None

    def _all(self) -> Iterator[Chunk]:
        """The chunk made ahead, then the rest of the run."""
        if self._first is not None:
            first, self._first = self._first, None
            yield first
        yield from self._it

    def chunks(self, stop: threading.Event) -> Iterator[Chunk]:
        # The simulator computes far faster than real time: pacing makes it look like a live bus.
        yield from paced(self._all(), stop, speed=self.speed, byte_seconds=self.byte_seconds, clock=self.clock)

    def close(self) -> None:
        self._it.close()
