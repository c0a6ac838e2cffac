"""The monitor on a port (a pty pair): decoded a gather at a time on the columnar path, the same records as a file."""

from __future__ import annotations

import os
import tty

import pytest

from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.sim import run
from rs30x_sniff.tui.app import make_app
from rs30x_sniff.sources.feeds import PortSource

from .helpers import SIZE, records_of

pytest.importorskip("serial")


async def test_a_port_shows_every_byte_and_the_records_a_file_would():
    chunks = list(run("hexapod", baud=230400, duration=0.5))
    data = b"".join(d for d, _ in chunks)
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        source = PortSource(os.ttyname(slave), 230400)
        app = make_app(source, DecodeOptions(baud=230400), post_interval=0)
        assert app.feeder.decoder.columnar  # a port is taken a gather at a time
        async with app.run_test(size=SIZE) as pilot:
            for i in range(0, len(data), 4096):
                os.write(master, data[i:i + 4096])
            for _ in range(200):
                await pilot.pause(0.05)
                if app.store.bytes_seen >= len(data):
                    break
            await pilot.pause(0.5)
            got = [app.store.get(s) for s in range(app.store.first_seq, app.store.end_seq)]
            await app.action_quit()
    finally:
        os.close(master)
        os.close(slave)
    want = records_of([(data, 0.0)], options=DecodeOptions(baud=230400))
    assert app.store.bytes_seen == len(data)
    # The last request may still wait for its reply (the port never closed): every record before it.
    assert [(r.kind, r.id, r.event.raw) for r in got] == [(r.kind, r.id, r.event.raw) for r in want][:len(got)]
    assert len(got) >= len(want) - 1
    assert app.servos.row_count == len({r.id for r in want if r.kind == "return"})  # a row per servo heard
