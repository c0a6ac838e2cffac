"""Model numbers of the Futaba family (issue 34 §2): a return of 0x3010, 0x3020 or 0x2040 names its model; the
RS405CB and RS406CB, whose numbers no source gives, are known by --model only, and M005 says so."""

from __future__ import annotations

import pytest

from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.lint import RULES, Linter
from rs30x_sniff.protocol.wire import encode_read, encode_return


def run(*frames: bytes, **options) -> tuple[list, Linter]:
    linter = Linter()
    dec = Decoder(DecodeOptions(**options), linter)
    records = dec.feed(b"".join(frames))
    records += dec.close()
    return records, linter


@pytest.mark.parametrize("number,model", [(0x3010, "RS301CR"), (0x3020, "RS302CD"), (0x2040, "RS204MD")])
def test_a_known_number_names_the_model_and_is_no_finding(number, model):
    records, linter = run(encode_read(1, 0, 2), encode_return(1, 0, number.to_bytes(2, "little")),
                          encode_read(1, 0x1E, 2))
    assert [f.code for f in linter.findings] == []
    assert records[-1].model.name == model  # the next request of that servo is decoded with its map


def test_m005_names_the_models_a_user_can_name_numbered_or_not():
    # A guessed RS405CB number (the digit pattern's 0x4050) is no known number: M005, listing every model.
    _, linter = run(encode_read(1, 0, 2), encode_return(1, 0, b"\x50\x40"))
    [finding] = linter.findings
    text = finding.message
    assert finding.code == "M005" and "0x4050" in text
    for known in ("0x3010 RS301CR", "0x3020 RS302CD", "0x2040 RS204MD", "0x3030 RS303MR", "0x3040 RS304MD"):
        assert known in text
    assert "RS405CB, RS406CB by --model only" in text
    assert "RS405CB, RS406CB by --model only" in RULES["M005"].doc


@pytest.mark.parametrize("model", ["RS405CB", "RS406CB"])
def test_an_unnumbered_model_is_taken_by_model_and_kept(model):
    # Its own map decodes the damper; a return of any model number learns nothing over --model.
    records, linter = run(encode_read(1, 20, 1), encode_return(1, 20, b"\x10"),
                          encode_read(1, 0, 2), encode_return(1, 0, b"\x50\x40"), models={1: model})
    assert {r.model.name for r in records} == {model}
    assert [(f.name, f.value) for f in records[1].fields] == [("damper", 16)]
    assert [f.code for f in linter.findings] == ["M005"] and f"{model} map" in linter.findings[0].message
