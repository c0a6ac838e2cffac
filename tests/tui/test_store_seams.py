"""The monitor's figures across a seam of the capture's clock: spans add up, the load restarts, nothing runs back."""

from __future__ import annotations

from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.sinks.pipeline import Sink, drive
from rs30x_sniff.sinks.stats import RecentLoad
from rs30x_sniff.tui.store import Store
from rs30x_sniff.protocol.wire import byte_time, encode_read, encode_return

BT = byte_time(115200)
READ, RET = encode_read(1, 0x2A, 2), encode_return(1, 0x2A, b"\x84\x03")


def part(seconds: float, every: float = 0.01):
    out, t = [], 0.0
    while t < seconds:
        out += [(READ, t), (RET, t + len(READ) * BT + 0.0002)]
        t += every
    return out


def records(chunks, columnar):
    got = []

    class Keep(Sink):
        takes_blocks = True

        def batch(self, step):
            got.extend(step)

    drive(chunks, Decoder(columnar=columnar), Keep())
    return got


def test_joined_captures_span_the_sum_of_their_parts_and_the_load_stays_true():
    a = part(2.0)
    for columnar in (False, True):
        one, two = Store(), Store()
        one.add(records(a, columnar))
        two.add(records(a + a, columnar))  # the clock restarts at 0 after 2 s
        assert abs(two.span - 2 * one.span) < 1e-9
        assert two.span > one.span > 0
        assert abs(two.bus_load - one.bus_load) < 1e-9 and 0 < two.bus_load < 1


def test_recent_load_starts_over_where_the_clock_restarts():
    load = RecentLoad(115200, 1.0)
    load.extend([(t / 100, 10) for t in range(300)])   # 3 s of 10-byte items every 10 ms
    busy = load.value
    load.extend([(t / 100, 10) for t in range(150)])   # a restart at 0
    assert abs(load.value - busy) < 1e-9  # the same traffic: the same load, not two seconds in one
