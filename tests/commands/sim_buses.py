"""Simulated buses the command tests compare: servos that answer later than the default."""

from __future__ import annotations

from rs30x_sniff.sim import SimBus


class DelayedBus(SimBus):
    """A bus whose servos answer after ``delay`` steps of their return delay (No. 7) each."""

    def __init__(self, baud: int, delay: int) -> None:
        super().__init__(baud)
        self.delay = delay

    def attach(self, servo):
        servo.mem[7] = self.delay
        return super().attach(servo)
