"""`export --table ... --format csv|parquet`: the issue's spelling of the tables, read back with csv and pyarrow."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from rs30x_sniff.cli import main

SESSION = str(Path(__file__).resolve().parents[2] / "captures" / "session-mixed.thex")


def _jsonl(capsys) -> list[dict]:
    assert main(["decode", SESSION, "--format", "jsonl", "--isolated"]) in (0, 1)
    return [json.loads(line) for line in capsys.readouterr().out.splitlines()]


@pytest.mark.parametrize("table", ["states", "transactions", "findings", "packets"])
def test_every_table_in_csv_and_parquet(capsys, tmp_path, table):
    pq = pytest.importorskip("pyarrow.parquet")
    out_csv, out_pq = tmp_path / f"{table}.csv", tmp_path / f"{table}.parquet"
    assert main(["export", SESSION, "--table", table, "-o", str(out_csv), "--isolated"]) == 0
    assert main(["export", SESSION, "--table", table, "--format", "parquet", "-o", str(out_pq), "--isolated"]) == 0
    rows = list(csv.DictReader(out_csv.open()))
    parquet = pq.read_table(out_pq)
    assert len(rows) == parquet.num_rows > 0
    assert list(rows[0]) == parquet.column_names and parquet.column_names[0] == "t"
    events = _jsonl(capsys)
    if table == "packets":
        assert len(rows) == sum(1 for e in events if e["type"] != "diagnostic")
        assert [int(r["offset"]) for r in rows] == [e["offset"] for e in events if e["type"] != "diagnostic"]
    elif table == "transactions":
        assert len(rows) == sum(1 for e in events if e["type"] == "short" and e["status"] in ("answered", "missing"))


def test_a_table_needs_its_name(capsys, tmp_path):
    assert main(["export", SESSION, "-o", str(tmp_path / "x.csv")]) == 2
    assert "a table is written by `table --of KIND`" in capsys.readouterr().err
