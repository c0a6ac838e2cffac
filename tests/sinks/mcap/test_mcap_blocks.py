"""convert on the columnar path writes the same messages as on the record path (io/mcap_blocks.py).

Every message (channel, log time, body) and each channel's order are the same; only the order of
messages of different channels within a 64 KiB group may differ (there they are in log-time order).
"""

import io
from collections import Counter

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from rs30x_sniff.decode import blocks
from rs30x_sniff.sinks.mcap.writer import McapSink
from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.sim import scenarios
from tests.decode.test_columnar import traffic


def convert(chunks, columnar: bool, options=None) -> tuple[list, list]:
    buf = io.BytesIO()
    with McapSink(buf, source="test", baud=115200, time_base="capture") as sink:
        drive(iter(chunks), Decoder(options, Linter(), columnar=columnar), sink)
    reader = make_reader(io.BytesIO(buf.getvalue()))
    msgs = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]
    return msgs, [(m.name, m.metadata) for m in reader.iter_metadata()]


def assert_same_content(chunks, options=None) -> None:
    a, meta_a = convert(chunks, False, options)
    b, meta_b = convert(chunks, True, options)
    assert Counter(b) == Counter(a)
    for topic in {m[0] for m in a}:
        assert [m for m in b if m[0] == topic] == [m for m in a if m[0] == topic], topic
    assert meta_b == meta_a


@pytest.mark.parametrize("name", sorted(scenarios.SCENARIOS))
def test_scenarios(name):
    assert_same_content(list(scenarios.run(name, duration=3.0)))


def test_untimed_and_mixed_models():
    chunks = [(d, None) for d, _ in traffic(3, 600, timed=True, gaps=False, faults=False, rare=0.05)]
    assert_same_content(chunks, DecodeOptions(models={2: "RS304MD"}))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10**6), n=st.integers(1, 300), timed=st.booleans(), rare=st.sampled_from([0.3, 0.03]),
       faults=st.booleans(), mixed=st.booleans())
def test_random_traffic(monkeypatch, seed, n, timed, rare, faults, mixed):
    monkeypatch.setattr(blocks, "MIN_BLOCK", 1)
    # mixed: servo 2 is an RS304MD among RS303MRs, so a long packet's records have two models
    assert_same_content(traffic(seed, n, timed=timed, gaps=True, faults=faults, rare=rare),
                        DecodeOptions(models={2: "RS304MD"}) if mixed else None)


def test_raw_messages_keep_stream_order_when_the_clock_goes_back():
    """A capture whose clock went back: the raw messages stay in stream order in the file (export
    reads them back in that order), while the rest is interleaved by log time."""
    import base64
    import json

    chunks = traffic(11, 400, timed=True, gaps=True, faults=True, rare=0.02)
    assert any(b[1] < a[1] for a, b in zip(chunks, chunks[1:]))  # the clock does go back
    msgs, _ = convert(chunks, True)
    raw = b"".join(base64.b64decode(json.loads(d)["data"]) for topic, _, d in msgs if topic == "/rs30x/raw")
    assert raw == b"".join(d for d, _ in chunks)
    assert_same_content(chunks)
