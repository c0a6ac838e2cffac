"""A small timed capture with fixed spacing, for the time-unit and rate tests (independent of the sample captures)."""

from __future__ import annotations

from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return


def gait(baud: int = 115200, cycles: int = 100) -> list[tuple[bytes, float]]:
    """A leg rig's bus from t = 0.5 s: every 20 ms a long packet of goals, 200 us later one servo's poll,
    its return 100 us after the poll. No two frames are back to back, so only the spacing of close
    neighbours (not a run of back-to-back bytes) can tell the rate. Times are whole microseconds."""
    bt = byte_time(baud)
    out: list[tuple[bytes, float]] = []
    for k in range(cycles):
        t = 0.5 + k * 0.02
        goals = encode_long(0x1E, [(sid, ((k * 7 + sid) % 200).to_bytes(2, "little")) for sid in range(1, 7)])
        sid = k % 6 + 1
        req, ret = encode_read(sid, 42, 18), encode_return(sid, 42, bytes(18))
        for frame, gap in ((goals, 200e-6), (req, 100e-6), (ret, 0.0)):
            out.append((frame, round(t, 6)))
            t += len(frame) * bt + gap
    return out
