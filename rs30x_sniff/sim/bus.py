"""The simulated half-duplex wire: orders host and servo bytes in time at baud-rate pacing."""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Iterable
from typing import cast

from ..protocol.events import LongPacket, ShortPacket
from ..decode.framing import FrameDecoder
from ..protocol.wire import DEFAULT_BAUD, byte_time
from .servo import Servo

Chunk = tuple[bytes, float]

# Host turnaround: the gap a host leaves after the line goes quiet before it transmits again.
DEFAULT_TURNAROUND = 50e-6


@dataclass(slots=True)
class Transmission:
    """Bytes one party drives onto the line, starting at ``start`` (seconds)."""

    start: float
    data: bytes
    source: str  # "host", "servo <id>" or "noise"

    def end(self, bt: float) -> float:
        return self.start + len(self.data) * bt


class SimBus:
    """A wire with one host and some servos.

    The host (a scenario script) calls :meth:`send`, :meth:`inject` and :meth:`sleep`; the servos
    see the host's bytes through the same frame decoder the sniffer uses and schedule their
    replies after their return delay. :meth:`drain` hands out the finished part of the line as
    ``(bytes, t)`` chunks in time order. Transmissions that overlap collide: the line carries the
    AND of the overlapping bytes (an idle-high, open-drain style line where a 0 bit wins).
    """

    def __init__(self, baud: int = DEFAULT_BAUD, servos: Iterable[Servo] = (), *,
                 turnaround: float = DEFAULT_TURNAROUND) -> None:
        self.baud = baud
        self.bt = byte_time(baud)
        self.servos: list[Servo] = list(servos)
        self.turnaround = turnaround
        self.t = 0.0              # the host's clock: it never goes back
        self.line_free = 0.0      # when everything scheduled so far has been sent
        self._pending: list[Transmission] = []
        self._rx = FrameDecoder(baud, gap_bytes=None)  # what the servos' UARTs make of the line
        self.bytes_out = 0
        self.log: list[Transmission] | None = None  # set to a list to keep every transmission

    # ---- the host's side ---------------------------------------------------------------------
    def attach(self, servo: Servo) -> Servo:
        """Plug a servo onto the bus (its clock starts now)."""
        servo.last_t = max(servo.last_t, self.t)
        self.servos.append(servo)
        return servo

    def detach(self, servo: Servo) -> None:
        self.servos.remove(servo)

    def sleep(self, seconds: float) -> None:
        self.t += max(0.0, seconds)

    def sleep_until(self, t: float) -> None:
        self.t = max(self.t, t)

    def send(self, data: bytes, *, at: float | None = None, wait: bool = True) -> list[Transmission]:
        """The host transmits ``data``; returns the replies it caused (already scheduled).

        With ``wait`` (the default) the host first waits for the line to be quiet (every reply
        scheduled so far sent) plus its turnaround; without it, it talks at ``at`` (or now) even
        over a reply that is still due: a protocol fault, used by the fault scenarios.
        """
        start = self.t if at is None else max(self.t, at)
        if wait:
            start = max(start, self.line_free + self.turnaround)
        self._put(Transmission(start, bytes(data), "host"))
        self.t = start + len(data) * self.bt
        return self._deliver(data, start)

    def inject(self, data: bytes, *, at: float | None = None) -> None:
        """Bytes from nowhere (noise, a glitch): on the line at ``at`` or now, seen by every servo."""
        start = self.t if at is None else max(self.t, at)
        self._put(Transmission(start, bytes(data), "noise"))
        self.t = start + len(data) * self.bt
        self._deliver(data, start)

    def wait_quiet(self) -> None:
        """The host waits until every scheduled reply has been sent."""
        self.t = max(self.t, self.line_free)

    # ---- servos ------------------------------------------------------------------------------
    def _deliver(self, data: bytes, start: float) -> list[Transmission]:
        replies = []
        for ev in self._rx.feed(data, start):
            if type(ev) is not ShortPacket and type(ev) is not LongPacket:
                continue
            done = cast(float, ev.t_end)  # every chunk fed here has its time, so every frame its end
            for servo in self.servos:
                if servo.baud != self.baud:
                    continue  # a servo at another rate sees only framing errors
                r = servo.receive(ev, done)
                if r is not None:
                    reply, delay = r
                    tx = Transmission(done + delay, reply, f"servo {servo.id}")
                    self._put(tx)
                    replies.append(tx)
        return replies

    def _put(self, tx: Transmission) -> None:
        self._pending.append(tx)
        self.line_free = max(self.line_free, tx.end(self.bt))
        self.bytes_out += len(tx.data)
        if self.log is not None:
            self.log.append(tx)

    # ---- output ------------------------------------------------------------------------------
    def drain(self, final: bool = False) -> list[Chunk]:
        """The line's finished chunks in time order: everything that ends before the host's clock
        (nothing later can collide with it), or everything when ``final``."""
        if not self._pending:
            return []
        bt = self.bt
        txs = sorted(self._pending, key=lambda x: x.start)
        horizon = float("inf") if final else self.t
        out: list[Chunk] = []
        keep: list[Transmission] = []
        i = 0
        while i < len(txs):
            group = [txs[i]]
            end = txs[i].end(bt)
            j = i + 1
            while j < len(txs) and txs[j].start < end - bt * 1e-6:
                group.append(txs[j])
                end = max(end, txs[j].end(bt))
                j += 1
            if end > horizon:
                keep += txs[i:]
                break
            out.append(_merge(group, bt))
            i = j
        self._pending = keep
        return out


def _merge(group: list[Transmission], bt: float) -> Chunk:
    """One chunk from transmissions that overlap in time (a collision ANDs their bytes)."""
    if len(group) == 1:
        return group[0].data, group[0].start
    base = group[0].start
    size = max(round((tx.start - base) / bt) + len(tx.data) for tx in group)
    line = bytearray(b"\xff" * size)
    for tx in group:
        k = round((tx.start - base) / bt)
        for n, b in enumerate(tx.data):
            line[k + n] &= b
    return bytes(line), base
