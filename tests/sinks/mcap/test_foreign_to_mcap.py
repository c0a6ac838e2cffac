"""Another tool's capture converted to MCAP says what the capture said: senders, UART errors, wall time."""

from datetime import datetime, timezone
from pathlib import Path

import pytest
from mcap.reader import make_reader

from rs30x_sniff.protocol.chunks import Marked, marks
from rs30x_sniff.cli import main
from rs30x_sniff.sources.captures import read_capture

FOREIGN = Path(__file__).resolve().parents[3] / "captures" / "foreign"


def _codes(capsys, path) -> list[str]:
    main(["lint", str(path), "--format", "github"])
    out = capsys.readouterr().out
    return sorted(line.split("title=")[1].split(" ")[0] for line in out.splitlines() if "title=" in line)


@pytest.mark.parametrize("name", ["saleae-logic2-iso.csv", "spy-swapped.log", "saleae-logic2.csv", "socat.log"])
def test_the_mcap_lints_like_the_capture_it_came_from(capsys, tmp_path, name):
    src = FOREIGN / name
    out = tmp_path / "x.mcap"
    assert main(["convert", str(src), "-o", str(out)]) == 0
    capsys.readouterr()
    assert _codes(capsys, out) == _codes(capsys, src)
    # Byte by byte (a reader may merge back-to-back bytes into one chunk when it knows the rate).
    want = [(b, marks(c)) for c in read_capture(str(src), warn=None) for b in c[0]]
    got = [(b, marks(c)) for c in read_capture(str(out), warn=None) for b in c[0]]
    assert got == want and any(m != (None, None) for _, m in want)


def test_flagged_bytes_and_senders_survive_the_conversion(tmp_path):
    out = tmp_path / "x.mcap"
    assert main(["convert", str(FOREIGN / "saleae-logic2-iso.csv"), "-o", str(out)]) == 0
    chunks = list(read_capture(str(out), warn=None))
    assert any(type(c) is Marked and c.error == "framing-error" for c in chunks)
    assert main(["convert", str(FOREIGN / "spy.log"), "-o", str(out), "--force"]) == 0
    senders = {marks(c)[0] for c in read_capture(str(out), warn=None)}
    assert senders == {"host", "servo"}


@pytest.mark.parametrize("name, when", [
    ("saleae-logic2-iso.csv", datetime(2026, 11, 22, 13, 14, 50, 250050, tzinfo=timezone.utc)),
    ("socat.log", None), ("jpnevulator.log", None),
])
def test_a_logged_wall_clock_anchors_the_mcap(tmp_path, name, when):
    out = tmp_path / "x.mcap"
    assert main(["convert", str(FOREIGN / name), "-o", str(out)]) == 0
    with open(out, "rb") as f:
        _, _, first = next(make_reader(f).iter_messages(topics=["/rs30x/raw"]))
    at = datetime.fromtimestamp(first.log_time / 1e9, timezone.utc)
    assert at.year == 2026  # not 1970: the log's own date and time
    if when is not None:
        assert abs((at - when).total_seconds()) < 1e-3
    # --start-time still wins over what the log says.
    assert main(["convert", str(FOREIGN / name), "-o", str(out), "--force", "--start-time", "2030-01-01T00:00:00Z"]) == 0
    with open(out, "rb") as f:
        _, _, first = next(make_reader(f).iter_messages(topics=["/rs30x/raw"]))
    at = datetime.fromtimestamp(first.log_time / 1e9, timezone.utc)
    assert abs((at - datetime(2030, 1, 1, tzinfo=timezone.utc)).total_seconds()) < 0.01  # the first stamp, less one chunk
