"""record --trigger on a pty fed by the simulator (issue 26): the overheat window holds the simulator's bytes
from --pre before the first matching return to --post after the last, and SIGTERM leaves it finalized."""

from __future__ import annotations

import json
import signal
import subprocess
import time

from mcap.reader import make_reader

from rs30x_sniff.sim import run
from rs30x_sniff.sinks.pipeline import decode_records
from rs30x_sniff.filters import parse_filter
from tests.e2e.helpers import Pty, assert_finalized_mcap, cli, recorded_bytes


def _finish(proc, timeout: float = 30.0):
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out.decode(), err.decode()


def test_overheat_window_covers_pre_before_the_first_fire_and_post_after_the_last(tmp_path):
    pty = Pty()
    folder = tmp_path / "box"
    proc = cli("record", pty.path, "-o", f"{folder}/", "--trigger", "present_temperature>70", "--pre", "1s",
               "--post", "2s", "--no-lint")
    try:
        deadline = time.monotonic() + 15
        while not folder.exists():  # made once the port is open
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read().decode()
            time.sleep(0.02)
        time.sleep(0.3)
        chunks = list(run("overheat"))
        pty.write_sim("overheat")
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)  # the window is still open (the bus has not gone --pre past it)
        rc, _, stderr = _finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
        pty.close()
    assert rc == 0, stderr
    (saved,) = sorted(folder.glob("*.mcap"))
    assert saved.name.endswith("-present_temperature-gt-70.mcap")
    assert_finalized_mcap(saved)
    flt = parse_filter("present_temperature>70")
    fires = [r.t for r in decode_records(chunks) if flt.matches(r)]
    data = b"".join(d for d, _ in chunks)
    offsets, pos = [], 0
    for d, t in chunks:
        offsets.append((t, pos))
        pos += len(d)
    got = recorded_bytes(saved)
    start = data.find(got)
    assert start >= 0 and got, "the window's bytes are one stretch of the simulator's"
    t_start = max(t for t, o in offsets if o <= start)
    t_end = max(t for t, o in offsets if o < start + len(got))
    # The window holds the chunks from fires[0] - pre to fires[-1] + post. Live times are arrival times: its
    # edges land within a few chunks of the simulator's (the first is after a quiet second of the scenario).
    first = min(t for t, _ in offsets if t >= fires[0] - 1.0)
    last = max(t for t, _ in offsets if t <= fires[-1] + 2.0)
    assert abs(t_start - first) < 0.15, (t_start, first)
    assert abs(t_end - last) < 0.15, (t_end, last)
    with open(saved, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["rs30x"]["trigger"] == "present_temperature>70" and int(meta["rs30x"]["fires"]) == len(fires)
    stats = json.loads(meta["rs30x.stats"]["stats"])
    assert stats["bytes"] == len(got)
    assert "saved" in stderr and "1 window saved" in stderr.splitlines()[-1]
