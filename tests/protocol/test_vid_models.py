"""A long packet's servo models are settled when the tracker builds its record, and the linter reads them there."""

from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.protocol.wire import encode_long, encode_read, encode_return
from tests.conftest import h


def run(chunks, linter=None, **opts):
    dec = Decoder(DecodeOptions(**opts), linter)
    out = []
    for data, t in chunks:
        out += dec.feed(data, t)
    out += dec.close()
    return out, dec


GOALS = encode_long(30, [(7, h("58 02 0D 00")), (8, h("58 02 0D 00"))])  # 60.0 deg in 0.13 s to IDs 7 and 8


def test_one_model_on_the_bus_settles_nothing_per_vid():
    recs, dec = run([(GOALS, None)])
    assert recs[0].vid_models is None
    assert recs[0].model is dec.bus.default
    assert [f.id for f in recs[0].fields] == [7, 7, 8, 8]


def test_mixed_models_are_settled_per_vid():
    recs, dec = run([(GOALS, None)], models={7: "RS304MD"})
    assert [m.name for m in recs[0].vid_models] == ["RS304MD", "RS303MR"]
    assert recs[0].model.name == "RS303MR"  # the record's own model stays the default
    assert [f.id for f in recs[0].fields] == [7, 7, 8, 8]


def test_a_model_learned_later_does_not_rewrite_an_earlier_long_packet():
    learn = encode_read(7, 0, 2) + encode_return(7, 0, h("40 30"))  # ID 7 says it is an RS304MD
    recs, dec = run([(GOALS + learn + GOALS, None)])  # one chunk: records leave the tracker together
    assert dec.bus.model_of(7).name == "RS304MD"
    assert recs[0].vid_models is None
    assert [m.name for m in recs[-1].vid_models] == ["RS304MD", "RS303MR"]


def test_the_linter_checks_each_vid_against_its_own_model():
    # 60 deg in 0.13 s: within an RS303MR's 0.11 s per 60 deg, too fast for an RS304MD's 0.16 s.
    start = encode_long(30, [(7, h("00 00 00 00")), (8, h("00 00 00 00"))])
    linter = Linter(LintConfig(select=["Q007"]))
    run([(start + GOALS, None)], linter, models={7: "RS304MD"})
    assert [(f.code, f.id) for f in linter.findings] == [("Q007", 7)]
    linter = Linter(LintConfig(select=["Q007"]))
    run([(start + GOALS, None)], linter)
    assert linter.findings == []
