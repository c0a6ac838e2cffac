"""Shared helpers for the monitor's tests: records from the manual's examples, a frozen clock, app factories."""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path

from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder

ROOT = Path(__file__).resolve().parents[2]
MANUAL = str(ROOT / "captures" / "manual-examples.hex")
SIZE = (160, 48)


def manual_records(linter=None):
    """Every record of captures/manual-examples.hex, decoded (with findings if a linter is given)."""
    dec = Decoder(DecodeOptions(), linter=linter)
    out = []
    for data, t in read_capture(MANUAL):
        out += dec.feed(data, t)
    return out + dec.close()


def records_of(chunks, linter=None, options=None):
    dec = Decoder(options or DecodeOptions(), linter=linter)
    out = []
    for data, t in chunks:
        out += dec.feed(data, t)
    return out + dec.close()


@dataclass(frozen=True)
class FakeFinding:
    """The shape of a lint finding, for store tests that need one of a chosen severity."""

    code: str
    name: str
    severity: str
    message: str
    offset: int
    t: float | None = None
    id: int | None = None


class GatedSource:
    """A live-looking source that pauses before the chunks at ``stops`` until ``gate`` is set."""

    name, kind, time_base = "gated", "port", "monotonic"
    live = True
    streamed = batched = False  # paced, its chunks not in gathers (sources.protocol.Pacing)

    def __init__(self, chunks, gate, stops=(), rearm: bool = False):
        self._chunks, self.gate, self.stops, self.rearm = chunks, gate, set(stops), rearm
        self.reached = threading.Event()  # set when the reader waits at a stop: all before it were read

    def chunks(self, stop):
        for i, c in enumerate(self._chunks):
            if i in self.stops:
                self.reached.set()
                self.gate.wait(5)
                if self.rearm:
                    self.gate.clear()
            yield c

    def close(self):
        pass


class FrozenClock:
    """A clock the test moves by hand (the header's elapsed time and value flashes read it)."""

    def __init__(self, t: float = 0.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


async def wait_done(pilot, app, limit: float = 10.0) -> None:
    """Let the capture thread finish and the screen catch up with it."""
    waited = 0.0
    while not app.done and waited < limit:
        await pilot.pause(0.02)
        waited += 0.02
    assert app.done, f"the capture thread did not finish: {[(w.name, w.state, w.error) for w in app.workers]}"
    await pilot.pause()
    await pilot.pause()
