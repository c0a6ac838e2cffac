"""A run of back-to-back intact frames as columns: what the framing kernel hands the columnar path."""

from __future__ import annotations

import numpy as np

from ..protocol.events import AnyEvent, frame_event
from ..protocol.wire import (
    AT_ADDRESS, AT_COUNT, AT_FLAG, AT_ID, AT_LENGTH, FRAME_OVERHEAD, LONG_PACKET_ID, RETURN_FIRST)

# What a row of a run (or a Block) is: a column of these codes, not an event object.
SHORT, LONG, RETURN = 0, 1, 2


class FrameRun:
    """Frames the numpy kernel took in one go (rs30x_sniff.decode.framing_kernel): every one complete, with a
    good Sum, each starting where the one before ended. Nothing per frame is a Python object.

    ``blob`` holds the run's bytes, its first byte at stream offset ``base``; ``starts``/``ends`` are
    each frame's bounds in ``blob``; ``t0``/``t1`` each frame's first-byte and end times (computed
    exactly as FrameDecoder.time_of does), or None for an untimed capture.
    """

    __slots__ = ("base", "blob", "starts", "ends", "t0", "t1", "_cols")

    def __init__(self, base: int, blob: bytes, starts: np.ndarray, ends: np.ndarray,
                 t0: np.ndarray | None, t1: np.ndarray | None) -> None:
        self.base, self.blob, self.starts, self.ends, self.t0, self.t1 = base, blob, starts, ends, t0, t1
        self._cols: dict | None = None

    def __len__(self) -> int:
        return len(self.starts)

    def __repr__(self) -> str:
        return f"<FrameRun {len(self)} frames @{self.base}+{len(self.blob)}>"

    @property
    def bytes_array(self) -> np.ndarray:
        return np.frombuffer(self.blob, dtype=np.uint8)

    @property
    def header_made(self) -> dict[str, np.ndarray] | None:
        """The header columns if header() has made them, else None (without making them)."""
        return self._cols

    def header(self) -> dict[str, np.ndarray]:
        """The header bytes of every frame as columns (chapter 4, "Format of Packets"), and its kind."""
        cols = self._cols
        if cols is None:
            a = self.bytes_array
            s = self.starts
            sid = a[s + AT_ID]
            is_return = a[s] == RETURN_FIRST
            kind = np.where(is_return, RETURN, np.where(sid == LONG_PACKET_ID, LONG, SHORT)).astype(np.uint8)
            cols = self._cols = {"kind": kind, "id": sid, "flag": a[s + AT_FLAG], "address": a[s + AT_ADDRESS],
                                 "length": a[s + AT_LENGTH], "count": a[s + AT_COUNT],
                                 "data_len": self.ends - s - FRAME_OVERHEAD}
        return cols

    def event(self, k: int) -> AnyEvent:
        """Frame ``k`` as the event the state machine would have made of it."""
        s, e = int(self.starts[k]), int(self.ends[k])
        t0 = t1 = None
        c0, c1 = self.t0, self.t1
        if c0 is not None and c1 is not None:  # (a timed run has both)
            t0, t1 = float(c0[k]), float(c1[k])
        return frame_event(self.base + s, self.blob[s:e], t0, t1, True)

    def events(self, lo: int = 0, hi: int | None = None) -> list[AnyEvent]:
        """Frames ``lo`` to ``hi`` as events (identical to the state machine's)."""
        hi = len(self) if hi is None else hi
        base, blob = self.base, self.blob
        starts, ends = self.starts[lo:hi].tolist(), self.ends[lo:hi].tolist()
        c0, c1 = self.t0, self.t1
        if c0 is None or c1 is None:  # (untimed: neither)
            return [frame_event(base + s, blob[s:e], None, None, True) for s, e in zip(starts, ends)]
        t0, t1 = c0[lo:hi].tolist(), c1[lo:hi].tolist()
        return [frame_event(base + s, blob[s:e], a, b, True) for s, e, a, b in zip(starts, ends, t0, t1)]
