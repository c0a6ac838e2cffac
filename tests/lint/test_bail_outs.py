"""Bail-outs belong to their rules: the rows the column path leaves to the record path (a crowded bus, a first
row after a cut, commands, flagged returns) are declared by the rules that need them (rs30x_sniff.lint.registry
BAIL_OUTS), and lint/batch asks the rules which to test."""

from pathlib import Path

from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.lint.registry import BAIL_OUTS, MEMORY_BAIL_OUTS, RULES, bail_outs
from rs30x_sniff.protocol.wire import byte_time, encode_return, encode_short

BT = byte_time(115200)


def test_each_bail_out_is_asked_by_the_rules_it_belongs_to():
    asked = {name for r in RULES for name in r.bails}
    assert asked | set(MEMORY_BAIL_OUTS) == set(BAIL_OUTS)
    assert RULES["Q008"].bails == ("crowded",) and RULES["B007"].bails == ("after-cut",)
    assert all("command" in r.bails for r in RULES if "command" in r.kinds)
    assert {r.code for r in RULES if "flagged" in r.bails} == {"P013", "S001", "S002", "S003", "S004"}
    # Whatever runs, the linter's memory (Shadows: reboots, the temperature lock) asks commands and flags.
    assert [b for b in bail_outs([])] == [BAIL_OUTS[n] for n in MEMORY_BAIL_OUTS]
    assert bail_outs([RULES["Q008"], RULES["B007"]]) == tuple(BAIL_OUTS.values())


def test_batch_names_no_bail_out_of_its_own():
    text = (Path(__file__).parents[2] / "rs30x_sniff" / "lint" / "batch.py").read_text()
    for own in ("max_servos", "COMMAND_BITS", "follows_cut", "Q008"):
        assert own not in text


def crowded_bus(servos: int = 30, cycles: int = 40) -> list[tuple[bytes, float]]:
    """Each servo polled in turn and answering: ``servos`` distinct IDs on one bus."""
    chunks, t = [], 1.0
    for _ in range(cycles):
        for sid in range(1, servos + 1):
            for fr in (encode_short(sid, 0x09, 0, b"", length=0, count=1), encode_return(sid, 42, bytes(18))):
                chunks.append((fr, t))
                t += len(fr) * BT + 0.0002
    return chunks


def lint(chunks, columnar: bool, **config):
    linter = Linter(LintConfig(**config))
    dec = Decoder(None, linter, columnar=columnar)
    on_columns = 0
    if columnar:
        for k in range(0, len(chunks), 200):
            step = dec.feed_many(chunks[k:k + 200])
            on_columns += sum(1 for x in step if type(x) is Block and not x.linted_by_rows)
        dec.close()
    else:
        for data, t in chunks:
            dec.feed(data, t)
        dec.close()
    return [(f.code, f.offset, f.message) for f in linter.findings], on_columns, linter


def test_a_crowded_bus_goes_row_by_row_only_for_q008():
    chunks = crowded_bus()
    found, on_columns, linter = lint(chunks, columnar=True)
    assert found == lint(chunks, columnar=False)[0] and [f[0] for f in found] == ["Q008"]
    assert on_columns <= 1  # a first part before the 25th ID at most: then every Block goes row by row for Q008
    # Without Q008 no rule asks the bail-out: the same (no) findings, on the columns, with the same memory.
    found, on_columns, quiet = lint(chunks, columnar=True, ignore=["Q008"])
    rows = lint(chunks, columnar=False, ignore=["Q008"])[2]
    assert found == [] and on_columns > 0
    # The IDs seen serve Q008 alone (the record path stops counting at the 25th); the rest of the memory is one.
    assert quiet.ids >= rows.ids >= set(range(1, 26)) and quiet.records == rows.records
    shadows = lambda lint: {i: tuple(getattr(s, k) for k in s.__slots__) for i, s in lint.servos.items()}  # noqa: E731
    assert shadows(quiet) == shadows(rows)
