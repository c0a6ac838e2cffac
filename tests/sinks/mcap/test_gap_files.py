"""A lost port is a seam in every file `record` writes (issue 31): one MCAP, numbered parts, black-box windows.

Read again, each file says what the live run said: one F010 where the port was lost, nothing paired across it,
durations and loads over the time the port was there, and no finding the same traffic without the loss lacks.
Built on the pieces `record` wires together (Parts, McapSink, BlackBox, the window writer) on simulator traffic,
with the loss at any point (hypothesis); tests/e2e/test_record_pty.py has the real port.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

from hypothesis import HealthCheck, given, settings, strategies as st
from mcap.reader import make_reader

from rs30x_sniff.sinks.windows import window_writer
from rs30x_sniff.sinks.parts import Parts
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder, Sink
from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.protocol.chunks import SourceGap
from rs30x_sniff.sim import run
from rs30x_sniff.sinks.blackbox import BlackBox, parse_trigger
from rs30x_sniff.sinks.mcap.writer import McapSink
from rs30x_sniff.sinks.pipeline import Pipeline, drive
from rs30x_sniff.sinks.stats import CaptureStats
from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.sources.mcap_reader import McapRawReader

EPOCH = 1.79e9  # a live recording's times are wall-clock seconds
BAUD = 115200


@lru_cache(maxsize=None)
def traffic(name: str) -> tuple:
    return tuple((d, t + EPOCH) for d, t in run(name, duration=1.5, seed=3))


def with_gap(chunks, cut: int, seconds: float) -> list:
    """The chunks with the port lost after chunk ``cut`` for ``seconds`` (later times moved on by it)."""
    before, after = list(chunks[:cut]), [(d, t + seconds) for d, t in chunks[cut:]]
    last = before[-1]
    lost_at = last[1] + len(last[0]) * 10 / BAUD
    return [*before, SourceGap(after[0][1], lost_at, "the port was gone (test)"), *after]


def live(chunks, *sinks, columnar: bool = False) -> tuple[list, CaptureStats]:
    """The live run, linted as it goes: record by record (record --print, --split-*), or on the columnar path in
    groups of about a second of the line (plain record to one file, the black box)."""
    linter = Linter(LintConfig())
    stats = CaptureStats(BAUD)
    Pipeline(Decoder(DecodeOptions(baud=BAUD), linter, columnar=columnar), [stats, *sinks],
             group_bytes=BAUD // 10).run(chunks)
    return [(f.code, f.offset) for f in linter.findings], stats


def read_again(path) -> tuple[list, dict]:
    """What `lint` and `info` make of a file: its findings (code, offset) and figures, on the columnar path."""
    linter = Linter(LintConfig())
    stats = CaptureStats(BAUD)
    drive(read_capture(str(path), warn=None), Decoder(DecodeOptions(baud=BAUD), linter, columnar=True), stats)
    return [(f.code, f.offset) for f in linter.findings], stats.as_dict()


def mcap_sink(path, part=0) -> McapSink:
    return McapSink(str(path) if not isinstance(path, str) else path, source="/dev/ttyTEST", baud=BAUD,
                    time_base="wall")


def raw_bytes(path) -> bytes:
    return b"".join(r[0] for r in McapRawReader(str(path), warn=None))


def codes(findings) -> set[str]:
    return {c for c, _ in findings}


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(["hexapod", "setup"]), where=st.floats(0.05, 0.95), seconds=st.floats(0.01, 30.0),
       columnar=st.booleans())
def test_one_file_says_what_the_live_run_said(tmp_path_factory, name, where, seconds, columnar):
    chunks = traffic(name)
    cut = max(1, min(len(chunks) - 1, int(len(chunks) * where)))
    out = tmp_path_factory.mktemp("one") / "rig.mcap"
    sink = mcap_sink(out)
    said, live_stats = live(with_gap(chunks, cut, seconds), sink, columnar=columnar)
    plain, plain_stats = live(list(chunks))
    got, figures = read_again(out)
    assert got == said  # the same findings at the same bytes
    assert [c for c, _ in got].count("F010") == 1 + [c for c, _ in plain].count("F010")
    assert codes(got) - {"F010"} <= codes(plain)
    live_figures = live_stats.as_dict()
    assert figures["segments"] == live_figures["segments"] == 2
    # The lost seconds are in neither the duration nor the load.
    assert abs(figures["duration_s"] - live_figures["duration_s"]) < 1e-6
    assert figures["duration_s"] <= plain_stats.as_dict()["duration_s"] + 1e-6
    assert raw_bytes(out) == b"".join(d for d, _ in chunks)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(where=st.floats(0.05, 0.95), seconds=st.floats(0.01, 30.0), by_time=st.booleans(),
       span=st.floats(0.1, 2.0))
def test_parts_carry_the_gap_in_the_part_with_bytes_on_both_sides(tmp_path_factory, where, seconds, by_time, span):
    chunks = traffic("hexapod")
    cut = max(1, min(len(chunks) - 1, int(len(chunks) * where)))
    folder = tmp_path_factory.mktemp("parts")
    gapped = with_gap(chunks, cut, seconds)
    # The parts' clock is the capture's: a part of ``span`` seconds, or of a size that makes several parts.
    now = [gapped[0][1]]

    def clock() -> float:
        return now[0]

    split = dict(split_seconds=span) if by_time else dict(split_bytes=max(1, int(span * 4000)))
    parts = Parts(str(folder / "bus.mcap"), mcap_sink, clock=clock, **split)

    class Tick(Sink):
        """Moves the parts' clock with the bytes, as a live port's arrival would."""

        def chunk(self, data, t, sender=None, error=None):
            now[0] = t

    said, _ = live(gapped, Tick(), parts)
    files = sorted(folder.iterdir())
    # A part ends at the first byte past its span (not at the first after the gap): with 1.5 s of traffic and a
    # gap, a span that reaches the end makes one part.
    timed = [c[1] for c in gapped if type(c) is not SourceGap]
    assert len(files) >= 2 or not (by_time and timed[-1] - timed[0] >= span + 0.1)
    per_file = {f.name: read_again(f)[0] for f in files}
    assert all(raw_bytes(f) for f in files), "a part without bytes"
    seams = {n: [c for c, _ in fs].count("F010") for n, fs in per_file.items()}
    assert sum(seams.values()) == 1, seams
    (holder,) = [Path(folder / n) for n, k in seams.items() if k]
    with open(holder, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    gaps = json.loads(meta["rs30x.gaps"]["gaps"])
    assert len(gaps) == 1 and 0 < gaps[0]["offset"] < len(raw_bytes(holder))  # bytes before and after it
    # Each part's own edges are a capture's start and end: nothing found there that whole traffic lacks.
    plain, _ = live(list(chunks))
    for fs in per_file.values():
        assert codes(fs) - {"F010"} <= codes(plain)
    assert b"".join(raw_bytes(f) for f in files) == b"".join(d for d, _ in chunks)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(where=st.floats(0.2, 0.8), seconds=st.floats(0.01, 30.0))
def test_a_window_that_spans_the_loss_carries_it(tmp_path_factory, where, seconds):
    chunks = traffic("hexapod")
    cut = max(1, min(len(chunks) - 1, int(len(chunks) * where)))
    folder = tmp_path_factory.mktemp("win")
    gapped = with_gap(chunks, cut, seconds)
    lines: list[str] = []
    save = window_writer(folder, opts=DecodeOptions(baud=BAUD), lint_config=LintConfig(), source="/dev/ttyTEST",
                         metadata=dict, keep=None, now=lambda: gapped[-1][1], say=lines.append)
    fire_at = gapped[cut + 1][1]  # the first byte after the gap
    trig = parse_trigger("kind:return", [])
    # A window of the whole traffic around the first reply after the gap: it spans the loss.
    box = BlackBox([trig], pre=120.0, post=120.0, save=save)
    live(gapped, box)
    files = sorted(folder.glob("*.mcap"))
    assert len(files) == 1, lines
    got, figures = read_again(files[0])
    assert [c for c, _ in got].count("F010") == 1 and figures["segments"] == 2
    assert "without the port: lost 1 time" in lines[0]
    assert box.saved[0][0] <= fire_at  # the first fire: a reply before the gap, so the window reaches across it


def test_an_older_file_with_only_the_gap_list_is_read_by_time(tmp_path):
    """A recording made before gaps named their byte: the list at its end is placed by the times."""
    chunks = traffic("hexapod")
    gapped = with_gap(chunks, len(chunks) // 2, 3.0)
    out = tmp_path / "old.mcap"
    sink = mcap_sink(out)
    gap = next(c for c in gapped if type(c) is SourceGap)
    # As the older writer did: the list at the end only, without offsets.
    sink.gap = lambda t, lost_at, note: sink.gaps.append({"lost_at": lost_at, "back_at": t,
                                                          "seconds": t - lost_at, "why": note})
    said, _ = live(gapped, sink)
    got, figures = read_again(out)
    assert got == said and figures["segments"] == 2
    assert any(type(c) is SourceGap and c[1] == gap[1] for c in read_capture(str(out), warn=None))


def test_a_cut_recording_keeps_its_gap(tmp_path):
    """A recorder killed after the port came back: no list at the end, the gap's own record still says it."""
    chunks = traffic("hexapod")
    gapped = with_gap(chunks, len(chunks) // 2, 3.0)
    out = tmp_path / "cut.mcap"
    sink = mcap_sink(out)
    said, _ = live(gapped, sink)
    data = out.read_bytes()
    with open(out, "rb") as f:
        last = make_reader(f).get_summary().chunk_indexes[-1]
    # Everything after the last chunk gone (the models, gaps and stats metadata, the summary), and half a record.
    (tmp_path / "killed.mcap").write_bytes(data[:last.chunk_start_offset + last.chunk_length + 5])
    got, figures = read_again(tmp_path / "killed.mcap")
    assert [c for c, _ in got].count("F010") == 1 and figures["segments"] == 2


def test_decode_and_pcapng_of_a_recording_show_the_gap_where_it_was(tmp_path, capsys):
    """decode's lines and JSON, and convert's pcapng, carry the F010 of a lost port before the first packet after
    it (a finding between records), as lint names it there."""
    from rs30x_sniff.cli import main

    chunks = traffic("hexapod")
    cut = len(chunks) // 2
    out = tmp_path / "rig.mcap"
    live(with_gap(chunks, cut, 3.0), mcap_sink(out))
    after = sum(len(d) for d, _ in chunks[:cut])  # the stream offset of the first byte after the gap
    assert main(["decode", str(out), "--isolated"]) == 0
    lines = capsys.readouterr().out.splitlines()
    (k,) = [i for i, line in enumerate(lines) if " F010 capture-seam: the port was gone (test)" in line]
    assert f"@{after} " in lines[k] and f"@{after} " in lines[k + 1] and " lint " not in lines[k + 1]
    assert main(["decode", str(out), "--isolated", "--format", "jsonl"]) == 0
    objs = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    (k,) = [i for i, o in enumerate(objs) if o["type"] == "diagnostic"]
    assert objs[k]["code"] == "F010" and objs[k + 1]["offset"] == after
    pcap = tmp_path / "rig.pcapng"
    assert main(["convert", str(out), "-o", str(pcap), "--isolated"]) == 0
    assert b"F010 capture-seam: the port was gone (test)" in pcap.read_bytes()
