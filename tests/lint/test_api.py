"""The lint contract other parts code against: Finding, Linter.feed/close, LintConfig, RULES."""

from __future__ import annotations

import pickle

import pytest

from rs30x_sniff.lint import RULES, ConfigError, Finding, LintConfig, Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.protocol.wire import encode_command, encode_short


def test_registry_shape():
    assert len(RULES) >= 40
    codes = RULES.codes()
    assert codes[0] == "F001" and len(set(codes)) == len(codes)
    for r in RULES:
        assert r.severity in ("error", "warning", "info") and r.summary and r.check
        assert RULES.get(r.name) is r and RULES.get(r.code.lower()) is r
    assert RULES.match("Q") == [c for c in codes if c[0] == "Q"]
    assert RULES.match("b00") == [f"B00{i}" for i in range(1, 10)]
    assert RULES.match("nothing-like-this") == []


def test_feed_returns_new_findings_and_close_the_late_ones():
    linter = Linter()
    dec = Decoder(DecodeOptions(), linter)
    recs = dec.feed(encode_short(1, 0x80, 0x1E, b"\x84\x03"))
    assert [f.code for f in recs[0].findings] == ["P001"]
    assert [f.code for f in linter.findings] == ["P001"]
    rec2 = dec.feed(encode_short(2, 0, 0x06, b"\x04"))[0]
    assert rec2.findings == []
    dec.close()
    assert [f.code for f in dec.late_findings] == ["Q001"]
    assert [f.code for f in rec2.findings] == ["Q001"]  # attached to the write it concerns
    assert [f.code for f in linter.findings] == ["P001", "Q001"]


def test_finding_json_and_pickle():
    f = Finding("P009", "combined-flash-reboot", "error", "msg", 86, None, 1, b"\xfa\xaf")
    assert f.as_json() == {"offset": 86, "t": None, "code": "P009", "name": "combined-flash-reboot",
                           "severity": "error", "message": "msg", "id": 1}
    assert pickle.loads(pickle.dumps(f)) == f


def test_config_selection_and_severity():
    cfg = LintConfig(select=["P", "checksum-mismatch"], ignore=["P00"], severity={"P012": "info"})
    # the P family but P00x, and F001 by its name: whatever P rules the registry holds
    family = [r.code for r in RULES if r.code.startswith("P") and not r.code.startswith("P00")]
    assert family and cfg.enabled_codes() == sorted(["F001", *family])
    assert cfg.severities()["P012"] == "info"
    with pytest.raises(ConfigError, match="unknown rule 'nope'"):
        LintConfig(ignore=["nope"]).enabled_codes()
    linter = Linter(LintConfig(select=["P009"], severity={"P009": "warning"}))
    dec = Decoder(DecodeOptions(), linter)
    dec.feed(encode_command(1, 0x60) + encode_short(1, 0x80, 0x1E, b"\x84\x03"))
    dec.close()
    assert [(f.code, f.severity) for f in linter.findings] == [("P009", "warning")]


def test_thresholds_come_from_the_config():
    chunks = [(encode_command(1, 0x40), 0.0), (encode_command(1, 0x20), 0.05)]
    for wait, expect in ((0.1, ["Q003"]), (0.02, [])):
        linter = Linter(LintConfig(flash_write_time=wait))
        dec = Decoder(DecodeOptions(), linter)
        for d, t in chunks:
            dec.feed(d, t)
        dec.close()
        assert [f.code for f in linter.findings] == expect
