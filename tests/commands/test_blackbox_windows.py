"""record --trigger's window files: a complete MCAP per window, never half-written, a stop asked for during a
save held until it is done, the oldest windows deleted under --keep; and the options' one-line errors."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest
from mcap.reader import make_reader

from rs30x_sniff.cli import main
from rs30x_sniff.sinks import windows as blackbox
from rs30x_sniff.sinks.parts import Keep
from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.lint import LintConfig
from rs30x_sniff.sim import run
from rs30x_sniff.sinks.blackbox import Trigger, Window
from rs30x_sniff.sources.mcap_reader import read_mcap_raw

T0 = 1_790_000_000.0


def writer(folder: Path, lines: list, keep=None):
    return blackbox.window_writer(folder, opts=DecodeOptions(), lint_config=LintConfig(), source="/dev/ttyTEST",
                                  metadata=lambda: {"port": "/dev/ttyTEST"}, keep=keep, now=lambda: T0 + 100,
                                  say=lines.append)


def window(chunks, text="present_temperature>70") -> Window:
    return Window(chunks[0][1], chunks[-1][1], Trigger(text), chunks[0][1] + 0.5, [(chunks[0][1] + 0.5, text)])


def chunks_of(name="overheat", duration=2.0, shift=0.0):
    return [(d, T0 + shift + t) for d, t in run(name, duration=duration)]


def test_a_window_is_a_complete_mcap_with_what_fired(tmp_path):
    lines: list[str] = []
    chunks = chunks_of()
    writer(tmp_path, lines)(chunks, window(chunks), "w.mcap")
    assert [p.name for p in tmp_path.iterdir()] == ["w.mcap"]
    assert b"".join(d for d, _ in read_mcap_raw(str(tmp_path / "w.mcap"))) == b"".join(d for d, _ in chunks)
    with open(tmp_path / "w.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None  # finalized
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert meta["rs30x"]["trigger"] == "present_temperature>70" and meta["rs30x"]["fires"] == "1"
    assert json.loads(meta["rs30x.stats"]["stats"])["bytes"] == sum(len(d) for d, _ in chunks)
    assert len(lines) == 1 and "saved" in lines[0] and "present_temperature>70" in lines[0]
    writer(tmp_path, lines)(chunks, window(chunks), "w.mcap")  # the same name again: a new file beside it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w-2.mcap", "w.mcap"]


def test_a_stop_during_a_save_comes_after_the_window_is_written(tmp_path, monkeypatch):
    chunks = chunks_of()
    real = blackbox.drive

    def drive_and_stop(*a, **kw):
        os.kill(os.getpid(), signal.SIGTERM)  # SIGTERM mid-save
        return real(*a, **kw)

    monkeypatch.setattr(blackbox, "drive", drive_and_stop)

    def stop(signum, frame):
        raise KeyboardInterrupt("SIGTERM")

    old = signal.signal(signal.SIGTERM, stop)
    try:
        with pytest.raises(KeyboardInterrupt):
            writer(tmp_path, [])(chunks, window(chunks), "w.mcap")
    finally:
        signal.signal(signal.SIGTERM, old)
    with open(tmp_path / "w.mcap", "rb") as f:
        assert make_reader(f).get_summary() is not None
    assert [p.name for p in tmp_path.iterdir()] == ["w.mcap"]


def test_keep_deletes_the_oldest_windows(tmp_path):
    lines: list[str] = []
    save = writer(tmp_path, lines, keep=Keep("3 windows", bytes=1))  # any size: only the newest stays
    for k in range(3):
        chunks = chunks_of(duration=0.5, shift=10.0 * k)
        save(chunks, window(chunks), f"2026-11-26T01-00-0{k}.000Z-x.mcap")
    assert [p.name for p in tmp_path.iterdir()] == ["2026-11-26T01-00-02.000Z-x.mcap"]
    assert sum("removed" in line for line in lines) == 2


@pytest.mark.parametrize("argv,why", [
    (["--trigger", "present_temperature>70", "-o", "-"], "give -o DIR/"),
    (["--trigger", "present_temperature>70", "-o", "{tmp}/nofolder"], "end it with /"),
    (["--trigger", "present_temprature>70", "-o", "{tmp}/w/"], "no register"),
    (["--trigger", "Z123", "-o", "{tmp}/w/"], "no such rule"),
    (["--trigger", "S001", "--pre", "soon", "-o", "{tmp}/w/"], "--pre soon"),
    (["--trigger", "S001", "--max-saves", "many", "-o", "{tmp}/w/"], "--max-saves many"),
    (["--trigger", "S001", "--split-time", "1min", "-o", "{tmp}/w/"], "--split-time: not with --trigger"),
    (["--trigger", "S001", "-o", "{tmp}/w/"], "cannot open port"),
    (["--pre", "30s", "-o", "{tmp}/w.mcap"], "--pre: only with --trigger"),
    (["--max-saves", "3/h", "-o", "{tmp}/w.mcap"], "--max-saves: only with --trigger"),
])
def test_bad_black_box_options_are_one_line_before_the_port_opens(tmp_path, capsys, argv, why):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(["record", "/dev/ttyDOES-NOT-EXIST", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and why in err[0], err
    assert not (tmp_path / "w").exists()  # nothing made for a run that never started
