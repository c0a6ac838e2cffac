"""A 0x0D read to an RS204MD (a return mode its map defines) is a read in every output: info's op counts and
the transactions table."""

from __future__ import annotations

import json

from rs30x_sniff.cli import main
from rs30x_sniff.sources.captures import write_capture
from tests.decode.test_model_return_modes import sim_capture


def _capture(tmp_path, model: str):
    path = tmp_path / f"{model}.thex"
    write_capture(path, sim_capture(model, ask_model=True, polls=80, every=20), "timestamped")
    return path


def test_info_counts_an_rs204md_0x0d_request_as_a_read(tmp_path, capsys):
    main(["info", str(_capture(tmp_path, "RS204MD")), "--format", "json"])
    info = json.loads(capsys.readouterr().out)
    assert info["by_op"] == {"read": 81}  # 1 model read, 76 polls, 4 area reads


def test_the_transactions_table_says_what_a_0x0d_read_asked_for(tmp_path, capsys):
    out = tmp_path / "tx.csv"
    main(["table", str(_capture(tmp_path, "RS204MD")), "--of", "transactions", "-o", str(out)])
    capsys.readouterr()
    header, *rows = [line.split(",") for line in out.read_text().splitlines()]
    col = {name: k for k, name in enumerate(header)}
    asked = [r for r in rows if r[col["read_address"]] == "60"]
    assert len(asked) == 4 and all(r[col["read_length"]] == "68" for r in asked)

