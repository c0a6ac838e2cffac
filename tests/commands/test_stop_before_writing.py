"""A stop that comes before the writer began (a SIGTERM as `convert` or `table` starts) says so in one line, exits
130 and leaves no file: an empty file in OUT's place would be neither a log nor the file it replaced."""

from __future__ import annotations

from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.commands import convert, table

CAPTURE = str(Path(__file__).resolve().parents[2] / "captures" / "manual-examples.hex")


def stop(*args, **kwargs):
    raise KeyboardInterrupt("SIGTERM")


@pytest.mark.parametrize("existing", [False, True])
def test_convert_stopped_before_its_writer_leaves_no_file(tmp_path, monkeypatch, capsys, existing):
    out = tmp_path / "bus.mcap"
    if existing:
        out.write_bytes(b"an older log")
    monkeypatch.setattr(convert, "open_mcap_sink", stop)
    argv = ["convert", CAPTURE, "-o", str(out), "--isolated"] + (["--force"] if existing else [])
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert err == f"rs30x-sniff: stopped (SIGTERM): {out}: nothing converted, nothing saved\n"
    assert (out.read_bytes() == b"an older log") if existing else not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == (["bus.mcap"] if existing else [])


def test_table_stopped_before_its_writer_leaves_no_file(tmp_path, monkeypatch, capsys):
    out = tmp_path / "states.csv"
    monkeypatch.setitem(table.SINKS, "states", stop)
    assert main(["table", CAPTURE, "--of", "states", "-o", str(out), "--isolated"]) == 130
    assert capsys.readouterr().err == f"rs30x-sniff: stopped (SIGTERM): {out}: nothing saved\n"
    assert list(tmp_path.iterdir()) == []
