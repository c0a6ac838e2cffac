"""`record`'s parts (issue 26): split by time as by size, --keep by age or total size, the oldest deleted first,
numbering that goes on after a restart; on a fake clock and a stand-in MCAP sink (tests/e2e has the real port)."""

from __future__ import annotations

import os

import pytest

from rs30x_sniff.commands.common import CliError
from rs30x_sniff.sinks.parts import Keep, Parts, parse_keep, parse_span


class FakeMcap:
    """What Parts asks of an McapSink: bytes written, chunks, finish."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.bytes_written = 0
        self.finished = False
        open(path, "wb").close()

    def chunk(self, data, t, sender=None, error=None) -> None:
        assert not self.finished
        with open(self.path, "ab") as f:
            f.write(data)
        self.bytes_written += len(data)

    def batch(self, step) -> None:
        pass

    def flush(self) -> None:
        pass

    def finish(self) -> None:
        self.finished = True


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def parts_of(tmp_path, **kw):
    clock = Clock()
    made: list[FakeMcap] = []

    def make(path, index):
        made.append(FakeMcap(path))
        return made[-1]

    def wall():
        return clock.t + 1.7e9  # an epoch time that moves with the clock

    said: list[str] = []
    p = Parts(str(tmp_path / "bus.mcap"), make, clock=clock, wall=wall, say=said.append, **kw)
    return p, clock, made, said


def age_files(paths):
    """Give each part still there the mtime it would have had: written up to its end (clock time)."""
    for path, t in paths:
        if os.path.exists(path):
            os.utime(path, (t + 1.7e9, t + 1.7e9))


def test_split_time_starts_a_part_every_span_each_finished(tmp_path):
    p, clock, made, _ = parts_of(tmp_path, split_seconds=60.0)
    for k in range(10):  # a chunk every 20 s: a part holds three
        p.chunk(bytes([k]) * 10, None)
        clock.t += 20.0
    p.close()
    names = [os.path.basename(m.path) for m in made]
    assert names == ["bus-001.mcap", "bus-002.mcap", "bus-003.mcap", "bus-004.mcap"]
    assert all(m.finished for m in made)
    assert [m.bytes_written for m in made] == [30, 30, 30, 10]
    assert b"".join((tmp_path / n).read_bytes() for n in names) == b"".join(bytes([k]) * 10 for k in range(10))


def test_an_idle_bus_makes_no_empty_parts(tmp_path):
    """A quiet port keeps its part open past its span; the next byte opens the next part: every part has bytes."""
    p, clock, made, _ = parts_of(tmp_path, split_seconds=5.0)
    p.chunk(b"\x07", None)
    for _ in range(12):  # a quiet port: the drive loop calls idle() (its empty chunks), every second here
        clock.t += 1.0
        p.idle()
    assert len(made) == 1 and not made[0].finished
    p.chunk(b"\x08", None)
    p.close()
    assert len(made) == 2 and all(m.finished and m.bytes_written == 1 for m in made)


def test_a_gap_stays_in_the_part_with_the_bytes_on_both_sides(tmp_path):
    """The port lost and found again past the part's span: the gap and the first bytes after it go in the part
    that holds the bytes before it, not alone into a part of their own."""
    gaps: list = []
    p, clock, made, _ = parts_of(tmp_path, split_seconds=5.0)
    p.chunk(b"\x07", None)
    clock.t += 30.0
    made[-1].gap = lambda *a: gaps.append((len(made), a))
    p.gap(1030.0, 1001.0, "lost")
    p.chunk(b"\x08", None)  # back: this byte is in part 1 with the gap
    p.chunk(b"\x09", None)  # and the part is past its span: this one opens part 2
    p.close()
    assert gaps == [(1, (1030.0, 1001.0, "lost"))]
    assert [m.bytes_written for m in made] == [2, 1]


def test_keep_size_holds_with_split_time_alone(tmp_path):
    """--keep SIZE with --split-time only: the folder never holds more than the size (a part ends at half of it),
    counted at every flush, not only when a part opens."""
    p, clock, made, _ = parts_of(tmp_path, split_seconds=3600.0, keep=Keep("200B", bytes=200))
    for _ in range(100):
        p.chunk(b"x" * 30, None)
        clock.t += 0.5
        total = sum(f.stat().st_size for f in tmp_path.iterdir())
        assert total <= 200 + 30, total  # the open part may hold the chunk just written past a flush
    p.close()
    assert sum(f.stat().st_size for f in tmp_path.iterdir()) <= 200
    assert len(made) > 10 and max(m.bytes_written for m in made) <= 100 + 30


def test_keep_size_deletes_the_oldest_closed_parts_first(tmp_path):
    p, clock, made, said = parts_of(tmp_path, split_bytes=100, keep=Keep("350B", bytes=350))
    for _ in range(12):
        p.chunk(b"x" * 50, None)
    p.close()
    left = sorted(f.name for f in tmp_path.iterdir())
    assert left == ["bus-004.mcap", "bus-005.mcap", "bus-006.mcap"]  # the newest, 300 bytes: under 350
    assert p.removed == 3 and [s.split()[2] for s in said] == [str(tmp_path / f"bus-00{i}.mcap") for i in (1, 2, 3)]
    assert "(3 older parts removed by --keep)" in p.describe()


def test_keep_age_deletes_closed_parts_older_than_it_never_the_open_one(tmp_path):
    p, clock, made, _ = parts_of(tmp_path, split_seconds=10.0, keep=Keep("25s", seconds=25.0))
    ends = []
    for _ in range(7):
        p.chunk(b"y" * 5, None)
        clock.t += 10.0
        ends.append((made[-1].path, clock.t))
        age_files(ends)
    p.chunk(b"z", None)  # opens part 8 at 1070 s; the parts that ended before 1045 s go
    left = sorted(f.name for f in tmp_path.iterdir())
    assert left == ["bus-005.mcap", "bus-006.mcap", "bus-007.mcap", "bus-008.mcap"]
    assert not made[-1].finished


def test_a_restarted_recorder_numbers_on_and_counts_the_old_parts(tmp_path):
    for i in (1, 2, 3):
        (tmp_path / f"bus-00{i}.mcap").write_bytes(b"o" * 100)
    (tmp_path / "other-004.mcap").write_bytes(b"x")
    p, clock, made, _ = parts_of(tmp_path, split_bytes=100, keep=Keep("250B", bytes=250))
    assert os.path.basename(made[0].path) == "bus-004.mcap"
    for _ in range(4):
        p.chunk(b"n" * 60, None)
    p.close()
    assert sorted(f.name for f in tmp_path.iterdir()) == ["bus-004.mcap", "bus-005.mcap", "other-004.mcap"]


def test_without_keep_an_existing_part_is_refused(tmp_path):
    (tmp_path / "bus-001.mcap").write_bytes(b"old")
    with pytest.raises(CliError, match="already exists"):
        parts_of(tmp_path, split_seconds=5.0)
    assert (tmp_path / "bus-001.mcap").read_bytes() == b"old"


@pytest.mark.parametrize("text,seconds", [("90", 90), ("90s", 90), ("500ms", 0.5), ("10min", 600), ("2h", 7200),
                                          ("1d", 86400), ("1.5 h", 5400)])
def test_spans(text, seconds):
    assert parse_span("--split-time", text) == pytest.approx(seconds)


@pytest.mark.parametrize("text", ["", "0", "-5s", "10 parsecs", "1e999s", "nan"])
def test_bad_spans_are_one_line(text):
    with pytest.raises(CliError) as e:
        parse_span("--split-time", text)
    assert "\n" not in str(e.value) and str(e.value).startswith("--split-time")


def test_keep_takes_an_age_or_a_size():
    assert parse_keep("24h") == Keep("24h", seconds=86400)
    assert parse_keep("5GB") == Keep("5GB", bytes=5 * 10**9)
    assert parse_keep("1.5GiB").bytes == int(1.5 * 2**30)
    for bad in ("24", "5 parsecs", "0GB", "-1h"):
        with pytest.raises(CliError, match="--keep"):
            parse_keep(bad)
