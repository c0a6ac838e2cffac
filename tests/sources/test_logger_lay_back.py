"""A serial logger's chunks laid back to their first byte: never past the previous chunk's arrival."""

from __future__ import annotations

import pytest
from hypothesis import given, strategies as st

from rs30x_sniff.cli import main
from rs30x_sniff.sources.timebase import to_first_byte
from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return

BT = byte_time(115200)


@given(st.lists(st.tuples(st.integers(1, 300), st.floats(0, 0.01)), min_size=1, max_size=40),
       st.floats(0, 10))
def test_increasing_stamps_never_lay_a_chunk_back_past_the_previous_one(steps, start):
    chunks, t = [], start
    for n, gap in steps:
        t += gap
        chunks.append((bytes(n), t))
    out = [t for _, t in to_first_byte(chunks, 115200)]
    assert out == sorted(out)
    for (data, stamp), first, prev in zip(chunks, out, [None, *(s for _, s in chunks)]):
        assert first <= stamp
        if prev is not None:
            assert first >= prev
            # Laid back by its whole length wherever that does not reach past the previous stamp.
            assert first == max(stamp - len(data) * BT, prev)


def test_a_restarted_clock_is_left_for_the_seam_to_tell():
    out = [t for _, t in to_first_byte([(bytes(8), 3.0), (bytes(8), 0.001), (bytes(10), 0.002)], 115200)]
    assert out[1] == pytest.approx(0.001 - 8 * BT)  # not held at 3.0: the log's own clock went back
    assert out[2] == pytest.approx(0.002 - 10 * BT)


def test_the_first_chunk_stops_at_the_logs_zero_unless_it_is_its_own_stamp():
    # spy:// counts from the port's opening: nothing was read before 0.
    assert next(to_first_byte([(bytes(8), 0.0003)], 115200))[1] == 0.0
    # socat and jpnevulator logs count from their first stamp: its bytes came before it.
    assert next(to_first_byte([(bytes(8), 0.0)], 115200))[1] == pytest.approx(-8 * BT)
    assert next(to_first_byte([(bytes(8), 5.0)], 115200))[1] == pytest.approx(5.0 - 8 * BT)


def _socat(blocks) -> str:
    """socat -x -v: a block per read, stamped when it returned (microseconds, 9 digits as socat 1.7.4)."""
    out, counts = [], {">": 0, "<": 0}
    for arrow, data, t in blocks:
        us = round(t * 1e6)
        out.append(f"{arrow} 2026/11/22 17:59:{41 + us // 1_000_000:02d}.{us % 1_000_000:09d}  length={len(data)} "
                   f"from={counts[arrow]} to={counts[arrow] + len(data) - 1}\n")
        counts[arrow] += len(data)
        out.append(" " + " ".join(f"{b:02x}" for b in data) + "\n--\n")
    return "".join(out)


def test_a_socat_log_whose_stamps_only_increase_keeps_its_clock(tmp_path, capsys):
    """socat read a poll late and the long write behind it at once: laid back by its 98 bytes, the
    write started before the poll's read returned, and the clock went backwards (F005)."""
    req, ret = encode_read(1, 0x2A, 2), encode_return(1, 0x2A, b"\x84\x03")
    write = encode_long(0x1E, [(i, bytes(4)) for i in range(1, 19)])  # 98 bytes
    blocks, t = [], 0.0
    for _ in range(3):
        blocks += [(">", req, t), ("<", ret, t + 0.0002 + len(ret) * BT)]
        blocks.append((">", write, t + 0.0040))  # 4 ms after the poll: 8.5 ms of bytes laid back
        t += 0.02
    path = tmp_path / "late.log"
    path.write_text(_socat(blocks))
    assert main(["lint", str(path), "--isolated", "--baud", "115200", "--select", "F005,F006,F010"]) == 0
    assert "0 findings" in capsys.readouterr().out
    assert main(["decode", str(path), "--isolated", "--baud", "115200", "--format", "jsonl"]) == 0
    import json

    events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    starts = [e["t"] for e in events if e.get("t") is not None]
    assert starts == sorted(starts) and len(starts) >= 9
