"""The monitor's capture thread and sources (no Textual): batches, lint findings, recording, pacing."""

from __future__ import annotations

import threading
import time

import pytest

from rs30x_sniff.sources.captures import CaptureError, read_capture, write_capture
from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.tui.feed import Feeder, default_linter
from rs30x_sniff.sim.source import SimulatorSource
from rs30x_sniff.sources.feeds import ChunkSource, FileSource, ReplaySource, paced
from rs30x_sniff.protocol.wire import encode_short

from .helpers import GatedSource, MANUAL


def run_feeder(source, **kw):
    batches = []
    feeder = Feeder(source, DecodeOptions(), batches.append, **kw)
    feeder.run()
    return feeder, batches


def test_a_file_arrives_whole_with_findings_and_servo_rows():
    feeder, batches = run_feeder(FileSource(MANUAL), linter=default_linter())
    assert batches[-1].done and batches[-1].error is None
    recs = [r for b in batches for r in b.records]
    assert [r.offset for r in recs][:3] == [0, 10, 18] and len(recs) == 24
    findings = [f for b in batches for f in b.findings]
    codes = {f.code for f in findings}
    # The manual's examples break its own rules; the late finding (Q002) comes with the last batch too.
    assert {"B002", "M002", "Q002"} <= codes
    assert len(findings) == len({id(f) for f in findings})
    assert batches[-1].servos[1].values["torque_enable"] == "brake"
    assert batches[-1].bytes_in == 253


def test_batches_are_cut_by_size():
    chunks = [(encode_short(1, 0, 30, b"\x00\x00"), i * 0.001) for i in range(100)]
    _, batches = run_feeder(ChunkSource("test", chunks), max_batch=30, interval=1e9)
    assert [len(b.records) for b in batches] == [30, 30, 30, 10]
    assert [b.done for b in batches] == [False, False, False, True]


def test_a_read_error_ends_the_capture_with_one_line(tmp_path):
    p = tmp_path / "bad.thex"
    p.write_text("0.0 FA AF 01\n0.1 FA ZZ\n")  # the first line reads fine, the second breaks mid-capture
    feeder, batches = run_feeder(FileSource(str(p)))
    assert batches[-1].done
    assert batches[-1].error == f"{p}:2: not a hex byte: 'ZZ'"
    assert [r.kind for b in batches for r in b.records] == ["garbage"]  # what came before the error is kept


def test_a_bad_file_fails_before_the_screen_starts(tmp_path):
    with pytest.raises(CaptureError, match="no such file"):
        FileSource(str(tmp_path / "nope.hex"))
    p = tmp_path / "bad.hex"
    p.write_text("FA AF 01\nFA ZZ\n")
    with pytest.raises(CaptureError, match="not a hex byte"):
        FileSource(str(p))


def test_recording_writes_an_mcap_of_what_follows(tmp_path):
    from rs30x_sniff.sources.mcap_reader import read_mcap_raw

    chunks = [(encode_short(1, 0, 30, bytes((i, 0))), i * 0.01) for i in range(50)]
    go = threading.Event()

    out = tmp_path / "rec.mcap"
    batches = []
    # The recording starts before chunk 10 is read.
    source = GatedSource(chunks, go, (10,))
    feeder = Feeder(source, DecodeOptions(), batches.append, interval=0)
    th = threading.Thread(target=feeder.run)
    th.start()
    assert source.reached.wait(5)  # the reader has taken chunks 0-9 (a loaded machine starts threads late)
    feeder.start_recording(str(out))
    go.set()
    th.join(5)
    assert not th.is_alive()
    notes = [b.note for b in batches if b.note]
    assert notes[0] == f"recording to {out}" and notes[-1] == f"saved {out}"
    assert feeder.recording is None  # the end of the source finished the file
    got = b"".join(d for d, _ in read_mcap_raw(str(out)))
    assert got == b"".join(d for d, _ in chunks[10:])


def test_stop_recording_finishes_the_file(tmp_path):
    from rs30x_sniff.sources.mcap_reader import read_mcap_raw

    release = threading.Event()

    class Slow:
        name, kind, time_base = "slow", "port", "monotonic"
        live = True
        streamed = batched = False  # paced, its chunks not in gathers (sources.protocol.Pacing)

        def chunks(self, stop):
            for i in range(40):
                if i == 20:
                    release.wait(5)
                yield encode_short(2, 0, 30, b"\x01\x00"), i * 0.01

        def close(self):
            pass

    out = tmp_path / "a.mcap"
    batches = []
    feeder = Feeder(Slow(), DecodeOptions(), batches.append, interval=0)
    feeder.start_recording(str(out))
    th = threading.Thread(target=feeder.run)
    th.start()
    deadline = time.monotonic() + 5
    while feeder.recording is None and time.monotonic() < deadline:
        time.sleep(0.01)
    feeder.stop_recording()
    release.set()
    th.join(5)
    data = b"".join(d for d, _ in read_mcap_raw(str(out)))
    assert 0 < len(data) <= 20 * 10 and len(data) % 10 == 0


def test_recording_to_an_unwritable_place_is_a_note_not_a_crash(tmp_path):
    feeder, batches = run_feeder(FileSource(MANUAL))
    f2 = Feeder(FileSource(MANUAL), DecodeOptions(), batches.append)
    f2.start_recording(str(tmp_path / "no" / "such" / "dir" / "x.mcap"))
    f2.run()
    assert any(b.note and b.note.startswith("cannot record to") for b in batches)
    assert batches[-1].done and batches[-1].error is None


def test_paced_follows_timestamps_and_line_rate():
    now = [0.0]
    waits = []

    class Stop(threading.Event):
        def wait(self, timeout=None):
            waits.append(round(timeout, 6))
            now[0] += timeout
            return False

    clock = lambda: now[0]  # noqa: E731
    out = list(paced([(b"ab", 10.0), (b"cd", 10.5), (b"ef", 12.0)], Stop(), speed=2.0, byte_seconds=0.001,
                     clock=clock))
    assert out == [(b"ab", 10.0), (b"cd", 10.5), (b"ef", 12.0)]
    assert waits == [0.25, 0.75]  # half a second and 1.5 s of capture, at twice the speed
    waits.clear()
    now[0] = 0.0
    out = list(paced([(bytes(100), None)], Stop(), speed=1.0, byte_seconds=0.001, clock=clock))
    assert [len(d) for d, _ in out] == [64, 36]
    assert waits == [0.064]


class Waits(threading.Event):
    """A stop event that notes each wait the replay asks for and advances a fake clock by it, or is set meanwhile."""

    def __init__(self, now: list[float], stop_in: float | None = None) -> None:
        super().__init__()
        self.now, self.stop_in, self.asked, self.returned = now, stop_in, [], []

    def wait(self, timeout=None):
        self.asked.append(round(timeout, 6))
        if self.stop_in is not None and self.stop_in < timeout:  # a stop arrives before the wait is over
            self.now[0] += self.stop_in
            self.set()
        else:
            self.now[0] += timeout
        self.returned.append(self.is_set())
        return self.is_set()


def test_replay_plays_a_timestamped_capture_at_its_own_pace(tmp_path):
    p = tmp_path / "t.thex"
    write_capture(p, [(encode_short(1, 0, 30, b"\x00\x00"), 0.1 * i) for i in range(5)], "timestamped")
    now = [0.0]
    src = ReplaySource(str(p), speed=4.0, clock=lambda: now[0])
    stop = Waits(now)
    chunks = list(src.chunks(stop))
    assert [t for _, t in chunks] == [0.0, 0.1, 0.2, 0.3, 0.4]
    # 0.1 s of capture between chunks, at 4x: a wait of 25 ms before each but the first (the pacing itself: above).
    assert stop.asked == [0.025] * 4 and now[0] == pytest.approx(0.1)


def test_a_stop_interrupts_a_replay(tmp_path):
    p = tmp_path / "t.thex"
    write_capture(p, [(b"\x07", 0.0), (b"\x07", 100.0)], "timestamped")
    now = [0.0]
    stop = Waits(now, stop_in=0.05)
    src = ReplaySource(str(p), clock=lambda: now[0])
    it = src.chunks(stop)
    assert next(it) == (b"\x07", 0.0)
    assert list(it) == []
    # The replay waited for the second chunk on the stop event itself, which the stop ended, not its 100 s.
    assert stop.asked == [100.0] and stop.returned == [True]


def test_a_stop_interrupts_a_replay_from_another_thread(tmp_path):
    p = tmp_path / "t.thex"
    write_capture(p, [(b"\x07", 0.0), (b"\x07", 100.0)], "timestamped")
    returned = []

    class Stop(threading.Event):
        def wait(self, timeout=None):
            returned.append(super().wait(timeout))
            return returned[-1]

    stop = Stop()
    it = ReplaySource(str(p)).chunks(stop)
    assert next(it) == (b"\x07", 0.0)
    threading.Timer(0.05, stop.set).start()
    assert list(it) == []
    assert returned == [True]  # the wait ended by the stop, not by its timeout


def test_the_simulator_source_runs_a_scenario():
    src = SimulatorSource("hexapod", 115200, speed=50.0, duration=0.5)
    stop = threading.Event()
    data = b"".join(d for d, _ in src.chunks(stop))
    assert data.startswith(b"\xfa\xaf")
    with pytest.raises(CaptureError, match="unknown scenario"):
        SimulatorSource("nope", 115200)
    with pytest.raises(CaptureError, match="cannot run at 1234"):
        SimulatorSource("hexapod", 1234)


def test_file_source_reads_what_read_capture_reads():
    src = FileSource(MANUAL)
    assert list(src.chunks(threading.Event())) == list(read_capture(MANUAL))
    assert src.time_base == "synthetic"


def test_a_source_that_fails_to_close_still_delivers_the_last_batch():
    class Broken:
        name, kind, time_base = "broken", "port", "monotonic"
        live = True
        streamed = batched = False  # paced, its chunks not in gathers (sources.protocol.Pacing)

        def chunks(self, stop):
            yield encode_short(1, 0, 30, b"\x00\x00"), 0.0

        def close(self):
            raise ValueError("signal only works in main thread")

    _, batches = run_feeder(Broken())
    assert batches[-1].done and len([r for b in batches for r in b.records]) == 1
    assert batches[-1].error == "closing the source: ValueError: signal only works in main thread"


def test_a_damaged_mcap_says_so_on_the_screen_not_behind_it(tmp_path, capsys):
    """Cut mid-chunk, the file is read up to the damage; the warning reaches the screen as a note."""
    from tests.sources.conftest import frames, make_mcap

    path = make_mcap(tmp_path / "cut.mcap", frames(200))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])
    feeder, batches = run_feeder(FileSource(str(path)), linter=default_linter())
    notes = [b.note for b in batches if b.note]
    assert batches[-1].done and sum(len(b.records) for b in batches) > 0
    assert notes and "cut.mcap" in notes[0]
    assert "warning" not in capsys.readouterr().err  # nothing printed behind the screen


@pytest.fixture
def read_ahead_all(monkeypatch):
    """Every file through a child process (io.read_ahead), however small."""
    from rs30x_sniff.sources import feeds as sources

    monkeypatch.setattr(sources, "READ_AHEAD_BYTES", 0)


def test_a_big_file_is_read_by_a_child_process_with_the_same_result(read_ahead_all, tmp_path):
    from rs30x_sniff.sources.read_ahead import ReadAhead

    src = FileSource(MANUAL)
    assert isinstance(src._it, ReadAhead) and not isinstance(ReplaySource(MANUAL)._it, ReadAhead)
    assert list(src.chunks(threading.Event())) == list(read_capture(MANUAL))
    assert src.time_base == "synthetic"
    _, batches = run_feeder(FileSource(MANUAL), linter=default_linter())
    findings = [f.code for b in batches for f in b.findings]
    assert [r.offset for b in batches for r in b.records][:3] == [0, 10, 18]
    assert {"B002", "M002", "Q002"} <= set(findings)


def test_a_child_read_error_ends_the_capture_with_one_line(read_ahead_all, tmp_path):
    p = tmp_path / "bad.thex"
    p.write_text("0.0 FA AF 01\n0.1 FA ZZ\n")
    src = FileSource(str(p))  # the head reads fine here
    _, batches = run_feeder(src)
    assert batches[-1].done and batches[-1].error == f"{p}:2: not a hex byte: 'ZZ'"
    assert [r.kind for b in batches for r in b.records] == ["garbage"]
    with pytest.raises(CaptureError, match="no such file"):
        FileSource(str(tmp_path / "nope.hex"))


def test_a_child_reads_a_damaged_mcap_and_the_note_comes_once(read_ahead_all, tmp_path, capsys):
    from tests.sources.conftest import frames, make_mcap

    path = make_mcap(tmp_path / "cut.mcap", frames(200))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])
    _, batches = run_feeder(FileSource(str(path)))
    notes = [b.note for b in batches if b.note]
    assert len(notes) == 1 and "cut.mcap" in notes[0] and notes[0].count("cut.mcap") == 1
    assert "warning" not in capsys.readouterr().err


def test_a_stopped_load_stops_the_child(read_ahead_all, tmp_path):
    p = tmp_path / "big.thex"
    write_capture(str(p), [(encode_short(1, 0, 30, b"\x00\x00"), i * 0.001) for i in range(100_000)], "timestamped")
    src = FileSource(str(p))
    stop = threading.Event()
    got = 0
    for _ in src.chunks(stop):
        got += 1
        if got == 1000:
            stop.set()
    src.close()
    assert got < 100_000 and src._it._proc.returncode is not None


def test_no_process_to_be_had_reads_the_file_here(read_ahead_all, monkeypatch):
    from rs30x_sniff.sources import read_ahead

    def no_process(*args, **kwargs):
        raise OSError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(read_ahead.subprocess, "Popen", no_process)
    src = FileSource(MANUAL)
    assert list(src.chunks(threading.Event())) == list(read_capture(MANUAL))
