"""The MCAP file as the Foxglove SDK writes it for us: our header, whole chunks, its own channels only, and
write errors raised as themselves."""

from __future__ import annotations

import io
import json

import pytest
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from rs30x_sniff import __version__
from rs30x_sniff.sinks.mcap.writer import McapSink
from rs30x_sniff.sources.mcap_reader import McapRawReader

from .conftest import hexapod_frames, to_mcap


def test_the_header_names_us_and_the_offsets_hold(tmp_path):
    """The SDK names itself in the header; the file says rs30x-sniff (a header of another length than
    the SDK's), and every offset in its summary still points at the record it names."""
    out = tmp_path / "h.mcap"
    to_mcap(hexapod_frames(600), out, chunk_size=16 * 1024)
    with open(out, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().library == f"rs30x-sniff {__version__}"
        assert reader.get_header().profile == ""
        summary = reader.get_summary()
        blob = out.read_bytes()
        assert len(summary.chunk_indexes) > 3
        for ci in summary.chunk_indexes:
            assert blob[ci.chunk_start_offset] == 0x06  # a chunk record starts there
            for offset in ci.message_index_offsets.values():
                assert blob[offset] == 0x07  # and a message index there
        # The seeking reader (summary, indexes) and a plain read of the records agree.
        by_index = [m.data for _, _, m in reader.iter_messages(log_time_order=False)]
    with open(out, "rb") as f:
        streamed = [r.data for r in StreamReader(f, validate_crcs=True).records if type(r).__name__ == "Message"]
    assert by_index == streamed and len(streamed) == summary.statistics.message_count


def test_messages_keep_their_times_and_channels_their_schemas(tmp_path):
    out = tmp_path / "m.mcap"
    to_mcap(hexapod_frames(200), out)
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert message.publish_time == message.log_time
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
            json.loads(message.data)
    # One schema record per schema name, shared by the 18 state channels.
    names = [s.name for s in summary.schemas.values()]
    assert sorted(names) == sorted(set(names)) and "rs30x.ServoState" in names
    assert sum(c.topic.startswith("/rs30x/servo/") for c in summary.channels.values()) == 18


def test_two_files_open_at_once_get_only_their_own_messages(tmp_path):
    """Each sink logs through a context of its own: a second file (the next part of a split recording,
    the monitor's recording beside `record`) never receives the first one's messages."""
    a = McapSink(str(tmp_path / "a.mcap"), source="a", baud=115200, time_base="capture")
    b = McapSink(str(tmp_path / "b.mcap"), source="b", baud=115200, time_base="capture")
    for i in range(50):
        a.raw(b"\xfa\xaf", i * 0.01)
        if i % 2:
            b.raw(b"\xfd\xdf", i * 0.01)
    a.finish()
    b.finish()
    assert [d for d, *_ in McapRawReader(str(tmp_path / "a.mcap"))] == [b"\xfa\xaf"] * 50
    assert [d for d, *_ in McapRawReader(str(tmp_path / "b.mcap"))] == [b"\xfd\xdf"] * 25


class _Failing(io.BytesIO):
    """A file whose writes fail once ``limit`` bytes are in it."""

    def __init__(self, limit: int, error: BaseException) -> None:
        super().__init__()
        self.limit = limit
        self.error = error

    def write(self, data) -> int:
        if self.tell() + len(data) > self.limit:
            raise self.error
        return super().write(data)


@pytest.mark.parametrize("error", [OSError(28, "No space left on device"), KeyboardInterrupt()])
def test_a_failed_write_is_raised_as_itself(error):
    """The SDK reports a failed write as its own RuntimeError; the sink raises the file's error: an
    OSError the CLI says in one line, a Ctrl-C during a write that stops the run as a stop."""
    out = _Failing(4000, error)
    sink = McapSink(out, source="s", baud=115200, time_base="capture", chunk_size=1000)
    with pytest.raises(type(error)) as e:
        for i in range(500):
            sink.raw(b"\xfa\xaf\x01" * 40, i * 0.01)
    assert e.value is error
    if isinstance(error, OSError):
        # The file stopped at its error; finish salvages it (cut to its last whole chunk, a footer of
        # its own) and says so, without the SDK's complaint about a broken writer.
        sink.finish()
        assert sink.failed is error and sink.finalized
        data = out.getvalue()
        assert len(data) == sink.readable_bytes <= 4000
        assert len(list(make_reader(io.BytesIO(data)).iter_messages())) > 0
    else:
        with pytest.raises(Exception):
            sink.finish()  # the writer is broken now; finish says so rather than pretend


def test_bytes_written_follows_the_file(tmp_path):
    out = tmp_path / "w.mcap"
    sink = McapSink(str(out), source="s", baud=115200, time_base="capture", chunk_size=1000)
    start = sink.bytes_written
    assert start > 0  # the header and the first metadata record
    for i in range(200):
        sink.raw(b"\xfa\xaf\x01" * 40, i * 0.01)
    sink.flush()
    assert sink.bytes_written == out.stat().st_size > start  # a flushed chunk is in the file
    sink.finish()
    assert sink.bytes_written == out.stat().st_size
