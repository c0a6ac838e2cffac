"""`table`: servo states, transactions and findings as CSV and Parquet, counted against decode, lint and convert."""

from __future__ import annotations

import csv
import io
import json
import sys
from collections import Counter

import pytest
from mcap.reader import make_reader

from rs30x_sniff.cli import main
from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.sinks.tables import PARQUET_HINT, ParquetTable, StatesTable
from rs30x_sniff.protocol.memmap import default_registry
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sinks.pipeline import drive

from ..conftest import CAPTURES

SESSION = CAPTURES / "session-mixed.thex"
KINDS = ("states", "transactions", "findings")

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")


def read_csv(path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def one_line_error(capsys, text: str) -> None:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rs30x-sniff: error:") and "Traceback" not in err, err
    assert text in err, err


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """What decode --format jsonl, lint --format json and convert say about the session capture."""
    d = tmp_path_factory.mktemp("ref")
    assert main(["decode", str(SESSION), "--format", "jsonl", "-o", str(d / "d.jsonl")]) == 0
    records = [json.loads(line) for line in open(d / "d.jsonl")]
    main(["lint", str(SESSION), "--format", "json", "-o", str(d / "l.json")])  # exit 1: the capture has errors
    findings = json.load(open(d / "l.json"))
    assert main(["convert", str(SESSION), "-o", str(d / "s.mcap")]) == 0
    states: Counter = Counter()
    last_state: dict[int, dict] = {}
    transactions = 0
    with open(d / "s.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.topic.startswith("/rs30x/servo/"):
                body = json.loads(message.data)
                states[body["id"]] += 1
                last_state[body["id"]] = body
            elif channel.topic == "/rs30x/transactions":
                transactions += 1
    return {"records": records, "findings": findings, "states": states, "last_state": last_state,
            "transactions": transactions}


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    """Every table of the session capture, in both formats: {(kind, fmt): path}."""
    d = tmp_path_factory.mktemp("tables")
    out = {}
    for kind in KINDS:
        for fmt in ("csv", "parquet"):
            path = d / f"{kind}.{fmt}"
            assert main(["table", str(SESSION), "--of", kind, "-o", str(path)]) == 0
            out[kind, fmt] = path
    return out


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_transactions_are_the_requests_that_expect_a_reply(tables, reference, fmt):
    expected = [r for r in reference["records"] if r.get("type") == "short" and r["status"] in ("answered", "missing")]
    assert len(expected) == reference["transactions"] > 0
    path = tables["transactions", fmt]
    rows = read_csv(path) if fmt == "csv" else pq.read_table(path).to_pylist()
    assert len(rows) == len(expected)
    assert [int(r["offset"]) for r in rows] == [r["offset"] for r in expected]
    assert Counter(r["status"] for r in rows) == Counter(r["status"] for r in expected)
    missing = [r for r in rows if r["status"] == "missing"]
    assert missing and all(r["latency_s"] in ("", None) for r in missing)
    first = rows[0]
    names = first["read_names"] if fmt == "parquet" else first["read_names"].split()
    assert names == expected[0]["read"]["names"]


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_findings_are_lints(tables, reference, fmt):
    path = tables["findings", fmt]
    rows = read_csv(path) if fmt == "csv" else pq.read_table(path).to_pylist()
    expected = reference["findings"]
    assert len(rows) == len(expected) > 0
    assert sorted((int(r["offset"]), r["code"]) for r in rows) == sorted((f["offset"], f["code"]) for f in expected)
    # A text capture: each finding's line and column, as lint's text report gives them.
    lines = SESSION.read_text().splitlines()
    for r in rows:
        line, col = int(r["line"]), int(r["column"])
        assert lines[line - 1][col - 1] in "0123456789ABCDEFabcdef"


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_states_match_the_mcap_state_channels(tables, reference, fmt):
    path = tables["states", fmt]
    rows = read_csv(path) if fmt == "csv" else pq.read_table(path).to_pylist()
    assert Counter(int(r["id"]) for r in rows) == reference["states"]
    last = {}
    for r in rows:
        last[int(r["id"])] = r
    for sid, body in reference["last_state"].items():
        row = last[sid]
        assert row["model"] == body["model"]
        for name, value in body.items():
            if name in ("id", "model", "t", "offset"):
                continue
            got = row[name]
            if isinstance(value, str):
                assert got == value, name
            elif fmt == "csv":
                assert float(got) == pytest.approx(value, abs=1e-6), name
            else:
                assert got == pytest.approx(value, abs=1e-6), name
        # Registers never seen for this servo are empty, not zero.
        unseen = set(row) - set(body) - {"wall_time"}
        assert all(row[n] in ("", None) for n in unseen), unseen


def test_parquet_columns_are_typed(tables):
    states = pq.read_schema(tables["states", "parquet"])
    assert states.field("t").type == pa.float64()
    assert states.field("id").type == pa.int64()
    assert states.field("model").type == pa.string()
    assert states.field("present_position").type == pa.float64()
    assert states.field("torque_enable").type == pa.string()
    assert states.field("servo_id").type == pa.int64()
    tx = pq.read_schema(tables["transactions", "parquet"])
    assert tx.field("read_names").type == pa.list_(pa.string())
    assert tx.field("latency_s").type == pa.float64()
    assert tx.field("reply_checksum_ok").type == pa.bool_()
    assert pq.read_schema(tables["findings", "parquet"]).field("line").type == pa.int64()


def test_parquet_is_written_in_row_groups(tmp_path):
    """A long capture is written as it is read: a row group per batch, never every row held at once."""
    path = tmp_path / "s.parquet"
    table = ParquetTable(str(path), batch_rows=100)
    sink = StatesTable(table, baud=115200, registry=default_registry())
    drive(read_capture(str(SESSION)), Decoder(DecodeOptions()), sink)
    assert sink.rows > 300
    assert pq.ParquetFile(path).metadata.num_row_groups == -(-sink.rows // 100)
    assert pq.read_table(path).num_rows == sink.rows


def test_epoch_times_add_a_wall_time_column(tmp_path):
    shifted = tmp_path / "wall.thex"
    t0 = 1_790_000_000.0
    with open(shifted, "w") as f:
        for line in SESSION.read_text().splitlines():
            body = line.partition("#")[0].split()
            if body:
                f.write(f"{t0 + float(body[0]):.6f} {' '.join(body[1:])}\n")
    assert main(["table", str(shifted), "--of", "transactions", "-o", str(tmp_path / "w.parquet")]) == 0
    assert main(["table", str(shifted), "--of", "transactions", "-o", str(tmp_path / "w.csv")]) == 0
    t = pq.read_table(tmp_path / "w.parquet")
    assert t.schema.field("wall_time").type == pa.timestamp("us", tz="UTC")
    first = t.slice(0, 1).to_pylist()[0]
    assert first["wall_time"].timestamp() == pytest.approx(first["t"], abs=1e-6)
    row = read_csv(tmp_path / "w.csv")[0]
    assert row["wall_time"].startswith("2026-") and row["wall_time"].endswith("+00:00")


def test_untimed_binary_capture_has_times_and_no_line_column(tmp_path):
    data = b"".join(d for d, _ in read_capture(str(SESSION)))
    binary = tmp_path / "s.bin"
    binary.write_bytes(data)
    assert main(["table", str(binary), "--of", "findings", "-o", str(tmp_path / "f.csv")]) == 0
    rows = read_csv(tmp_path / "f.csv")
    assert rows and "line" not in rows[0] and "wall_time" not in rows[0]
    assert all(float(r["t"]) == pytest.approx(int(r["offset"]) * 10 / 115200) for r in rows)


def test_stdout_csv(capsys):
    assert main(["table", str(SESSION), "--of", "transactions", "-o", "-"]) == 0
    out = capsys.readouterr().out
    rows = list(csv.DictReader(io.StringIO(out)))
    assert len(rows) == 128 and rows[0]["op"] == "read"


def test_refuses_to_overwrite_without_force(tmp_path, capsys):
    out = tmp_path / "t.csv"
    out.write_text("precious")
    assert main(["table", str(SESSION), "--of", "states", "-o", str(out)]) == 2
    one_line_error(capsys, "already exists")
    assert out.read_text() == "precious"
    assert main(["table", str(SESSION), "--of", "states", "-o", str(out), "--force"]) == 0
    assert read_csv(out)
    assert [p.name for p in tmp_path.iterdir()] == ["t.csv"]  # no temporary file left beside it


def test_refuses_to_overwrite_the_input(tmp_path, capsys):
    copy = tmp_path / "s.csv"
    copy.write_bytes(SESSION.read_bytes())
    assert main(["table", str(copy), "--of", "states", "-o", str(copy), "--force", "--input-format",
                 "timestamped"]) == 2
    one_line_error(capsys, "is the input file")


def test_unknown_extension_and_findings_without_lint(tmp_path, capsys):
    assert main(["table", str(SESSION), "--of", "states", "-o", str(tmp_path / "t.xlsx")]) == 2
    one_line_error(capsys, "--format")
    assert main(["table", str(SESSION), "--of", "findings", "--no-lint", "-o", str(tmp_path / "f.csv")]) == 2
    one_line_error(capsys, "--no-lint")
    assert not list(tmp_path.iterdir())


def test_missing_pyarrow_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow now raises ImportError
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    out = tmp_path / "s.parquet"
    assert main(["table", str(SESSION), "--of", "states", "-o", str(out)]) == 2
    one_line_error(capsys, PARQUET_HINT)
    assert not out.exists()
    # CSV needs no pyarrow.
    assert main(["table", str(SESSION), "--of", "states", "-o", str(tmp_path / "s.csv")]) == 0


def _mcap_counts(path) -> tuple[Counter, int]:
    states: Counter = Counter()
    transactions = 0
    with open(path, "rb") as f:
        for _, channel, _ in make_reader(f).iter_messages():
            if channel.topic.startswith("/rs30x/servo/"):
                states[channel.topic] += 1
            elif channel.topic == "/rs30x/transactions":
                transactions += 1
    return states, transactions


@pytest.mark.parametrize("capture", sorted(CAPTURES.glob("**/*hex")), ids=lambda p: p.name)
def test_every_capture_matches_its_mcap(tmp_path, capture):
    """States and transactions rows are the MCAP's state and transaction messages, capture by capture
    (the lint examples hold ACK requests, NACKs, broadcasts and long packets)."""
    assert main(["convert", str(capture), "-o", str(tmp_path / "c.mcap"), "--no-lint"]) == 0
    states, transactions = _mcap_counts(tmp_path / "c.mcap")
    for kind in ("states", "transactions"):
        assert main(["table", str(capture), "--of", kind, "-o", str(tmp_path / f"{kind}.csv")]) == 0
    rows = read_csv(tmp_path / "states.csv")
    assert Counter(f"/rs30x/servo/{r['id']}/state" for r in rows) == states
    assert len(read_csv(tmp_path / "transactions.csv")) == transactions


def test_register_columns_are_the_union_of_the_models():
    from rs30x_sniff.sinks.tables import FLOAT, INT, STR, register_columns

    registry = default_registry()
    columns = dict(register_columns(registry))
    names = {r.name for m in registry.models.values() for r in m.registers if r.name}
    assert set(columns) == names
    assert columns["present_position"] == FLOAT and columns["servo_id"] == INT and columns["torque_enable"] == STR
