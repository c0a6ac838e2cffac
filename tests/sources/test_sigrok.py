"""sigrok captures: .sr sessions (decoded from the samples here) and sigrok-cli's uart annotation text."""

from __future__ import annotations

import json
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

np = pytest.importorskip("numpy", reason="logic captures need numpy")

from rs30x_sniff.protocol.chunks import FRAMING_ERROR, Marked  # noqa: E402
from rs30x_sniff.cli import main  # noqa: E402
from rs30x_sniff.decode.framing import FrameDecoder  # noqa: E402
from rs30x_sniff.sources.captures import CaptureError, detect_format, read_capture, write_capture  # noqa: E402
from rs30x_sniff.sources.inputs import read_input  # noqa: E402
from rs30x_sniff.sources.uart import encode  # noqa: E402
from rs30x_sniff.sim import run  # noqa: E402
from rs30x_sniff.protocol.wire import BAUD_RATES, byte_time  # noqa: E402
from tests.conftest import CAPTURES  # noqa: E402

SIGROK_CLI = shutil.which("sigrok-cli")
needs_sigrok = pytest.mark.skipif(SIGROK_CLI is None, reason="sigrok-cli is not installed (apt-get install sigrok-cli)")
SAMPLE = CAPTURES / "foreign" / "sigrok-hexapod.sr"
ANNOTATIONS = CAPTURES / "foreign" / "sigrok-uart.txt"
LEAD = 1e-3  # idle line before the first byte in the captures made here


# ---- helpers -------------------------------------------------------------------------------------
def sim(baud: int, duration: float = 1.1) -> list[tuple[bytes, float]]:
    """The simulator's hexapod at ``baud``; a rate the servos cannot run at is the 115200 bus sped up."""
    if baud in BAUD_RATES:
        return list(run("hexapod", baud=baud, duration=duration))
    k = 115200 / baud
    return [(d, t * k) for d, t in run("hexapod", baud=115200, duration=duration / k)]


def sigrok_sr(path: Path, channels: dict[str, np.ndarray], rate: float) -> Path:
    """A .sr made by sigrok-cli from raw samples (one byte per sample, channel k in bit k)."""
    lines = list(channels.values())
    n = max(len(x) for x in lines)
    raw = np.zeros(n, np.uint8)
    for k, x in enumerate(lines):
        full = np.ones(n, bool)
        full[:len(x)] = x
        raw |= full.astype(np.uint8) << k
    binary = path.with_suffix(".bin")
    raw.tofile(binary)
    names = ",".join(f"{k}={name}" for k, name in enumerate(channels))
    subprocess.run([SIGROK_CLI, "-I", f"binary:numchannels={len(lines)}:samplerate={int(rate)}", "-i", str(binary),
                    "-C", names, "-o", str(path)], check=True, capture_output=True)
    binary.unlink()
    return path


def annotate(sr: Path, channel: str, baud: int, *extra: str, classes: str = "rx-data") -> str:
    """sigrok-cli's own uart decoder run on ``sr``: its annotation text."""
    out = subprocess.run([SIGROK_CLI, "-i", str(sr), "-P", f"uart:rx={channel}:baudrate={baud}", "-A",
                          f"uart={classes}", "--protocol-decoder-samplenum", *extra],
                         check=True, capture_output=True, text=True)
    return out.stdout


def hand_sr(path: Path, samples: bytes | None = b"", *, metadata: str | None = None, version: str = "2",
            unitsize: int = 1, probes: str = "probe1=D0\n") -> Path:
    """A .sr written here (for the cases sigrok-cli does not make): one logic chunk of raw units."""
    meta = metadata if metadata is not None else (
        "[global]\nsigrok version=0.5.2\n\n[device 1]\ncapturefile=logic-1\ntotal probes=8\n"
        f"samplerate=1 MHz\ntotal analog=0\n{probes}unitsize={unitsize}\n")
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("version", version)
        z.writestr("metadata", meta)
        if samples is not None:
            z.writestr("logic-1-1", samples)
    return path


def chunks_of(path: Path, **options) -> list:
    return list(read_capture(str(path), options=options))


def payload(chunks) -> bytes:
    return b"".join(c[0] for c in chunks)


def events_of(chunks, baud: int) -> list:
    """Frame events, with the bytes a chunk's UART flagged made garbage (as the pipeline does)."""
    dec = FrameDecoder(baud)
    out = []
    for c in chunks:
        error = c.error if type(c) is Marked else None
        out += dec.feed(c[0], c[1]) if error is None else dec.feed_fault(c[0], c[1], error)
    return out + dec.close()


def packets(chunks, baud: int) -> list[tuple[str, bytes, float | None]]:
    return [(e.kind, bytes(e.raw), e.t_start) for e in events_of(chunks, baud)]


def same_packets(a, b, tolerance: float, shift: float = 0.0) -> None:
    assert [(k, r) for k, r, _ in a] == [(k, r) for k, r, _ in b]
    worst = max(abs(ta - tb - shift) for (_, _, ta), (_, _, tb) in zip(a, b))
    assert worst <= tolerance, worst


def jsonl(capsys, *argv: str) -> tuple[list[dict], str]:
    assert main(["decode", *argv, "--format", "jsonl", "--isolated"]) == 0
    cap = capsys.readouterr()
    return [json.loads(line) for line in cap.out.splitlines()], cap.err


def comparable(records: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in ("t", "t_end", "latency_s")} for r in records]


# ---- the samples -----------------------------------------------------------------------------------
# The golden figures of captures/foreign/sigrok-*: what the simulator's hexapod sent (sigrok.md).
SAMPLE_BYTES = 666
SAMPLE_KINDS = {"short": 21, "return": 21, "long": 3}
FIRST_LINE = "    0.001050 @0        host  READ id=1 read[model_number]"


def test_golden_sr_sample(capsys):
    """The bundled .sr: its rate found from the samples, the packets the simulator sent, 1 ms later."""
    recs, err = jsonl(capsys, str(SAMPLE))
    assert "115200 bit/s, found from the samples of channel D0" in err
    kinds: dict[str, int] = {}
    for r in recs:
        kinds[r["type"]] = kinds.get(r["type"], 0) + 1
    assert kinds == SAMPLE_KINDS
    assert all(r["checksum_ok"] and not r["diagnostics"] for r in recs)
    raw = bytes.fromhex("".join(r["raw"] for r in recs))
    assert len(raw) == SAMPLE_BYTES
    sent = sim(115200, 1.05)
    assert raw == payload(sent)
    same_packets(packets(chunks_of(SAMPLE), 115200), packets(sent, 115200), 1.5e-6, shift=LEAD)
    assert main(["decode", str(SAMPLE), "--isolated"]) == 0
    assert capsys.readouterr().out.splitlines()[0].startswith(FIRST_LINE)


def test_golden_annotation_sample(capsys):
    """sigrok-cli's annotations of the same capture: the same packets, times within a byte time."""
    recs, err = jsonl(capsys, str(ANNOTATIONS), "--baud", "115200")
    assert "warning" not in err
    sr, _ = jsonl(capsys, str(SAMPLE))
    assert comparable(recs) == comparable(sr)
    worst = max(abs(a["t"] - b["t"]) for a, b in zip(recs, sr))
    assert worst < byte_time(115200)
    assert detect_format(str(ANNOTATIONS)) == "sigrok-uart" and detect_format(str(SAMPLE)) == "sigrok"


def test_annotations_without_a_baud_assume_the_default_and_say_so(capsys):
    recs, err = jsonl(capsys, str(ANNOTATIONS))
    assert "times assume the uart decoder ran at 115200 bit/s" in err and len(recs) == 45


def test_info_reports_the_rate_found_and_where_it_came_from(capsys):
    assert main(["info", str(SAMPLE), "--format", "json", "--isolated"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["baud"] == 115200 and info["bytes"] == SAMPLE_BYTES
    assert info["settings"]["origin"]["baud"].startswith("capture (found from the samples of channel D0")
    assert info["settings"]["time_ref"] == "first"


def test_baud_overrides_the_rate_the_samples_show(capsys):
    assert main(["info", str(SAMPLE), "--format", "json", "--isolated", "--baud", "57600"]) == 0
    cap = capsys.readouterr()
    info = json.loads(cap.out)
    assert info["baud"] == 57600 and info["settings"]["origin"]["baud"] == "command line"
    assert "found from the samples" not in cap.err
    assert info["garbage_bytes"] > 0  # read at the wrong rate, as asked


def test_lint_and_convert_read_the_sample(capsys, tmp_path):
    assert main(["lint", str(SAMPLE), "--isolated"]) == 0
    out = tmp_path / "hexapod.mcap"
    assert main(["convert", str(SAMPLE), "-o", str(out), "--isolated"]) == 0
    capsys.readouterr()
    mcap, _ = jsonl(capsys, str(out))
    sr, _ = jsonl(capsys, str(SAMPLE))
    assert comparable(mcap) == comparable(sr)
    assert all(abs(a["t"] - b["t"]) < 1e-6 for a, b in zip(mcap, sr))


def test_the_monitor_reads_a_logic_capture_with_its_options():
    import threading

    from rs30x_sniff.sources.feeds import FileSource, ReplaySource

    src = FileSource(str(SAMPLE), options={"channel": "D0", "baud": 115200})
    assert payload(src.chunks(threading.Event())) == payload(sim(115200, 1.05))
    with pytest.raises(CaptureError, match="no channel 'D7'"):
        ReplaySource(str(SAMPLE), options={"channel": "D7", "baud": None})


# ---- round trips through sigrok-cli ---------------------------------------------------------------
@needs_sigrok
@pytest.mark.parametrize("baud,rate", [(9600, 250_000), (115200, 1_000_000), (460800, 4_000_000)])
def test_a_simulated_bus_through_sigrok_cli_decodes_like_the_simulator(capsys, tmp_path, baud, rate):
    """The issue's check: at 9600, 115200 and 460800 bit/s the rate is found from the samples and the
    packets (every field, finding and pairing) are the simulator's own capture's."""
    sent = sim(baud, 1.6 if baud == 9600 else 1.1)
    thex = tmp_path / "sim.thex"
    write_capture(thex, sent, "timestamped")
    sr = sigrok_sr(tmp_path / "sim.sr", {"D0": encode(sent, rate, baud, lead=LEAD)}, rate)
    got, err = jsonl(capsys, str(sr))
    assert f"{baud} bit/s, found from the samples of channel D0" in err
    want, _ = jsonl(capsys, str(thex), "--baud", str(baud), "--baud-any")
    assert comparable(got) == comparable(want)
    assert all(abs(a["t"] - b["t"] - LEAD) < byte_time(baud) for a, b in zip(got, want))
    # Round trip: the same bytes, each chunk's time within a byte time of the simulator's.
    back = chunks_of(sr)
    assert payload(back) == payload(sent)
    same_packets(packets(back, baud), packets(sent, baud), byte_time(baud), shift=LEAD)


@needs_sigrok
def test_sigrok_cli_annotations_round_trip(tmp_path):
    baud, rate = 57600, 1_000_000
    sent = sim(baud, 1.1)
    sr = sigrok_sr(tmp_path / "sim.sr", {"D0": encode(sent, rate, baud, lead=LEAD)}, rate)
    for extra in ((), ("-l", "4")):  # plain, and with the annotation class and quotes
        text = tmp_path / "ann.txt"
        text.write_text(annotate(sr, "D0", baud, *extra))
        back = chunks_of(text, baud=baud)
        assert payload(back) == payload(sent)
        same_packets(packets(back, baud), packets(sent, baud), byte_time(baud), shift=LEAD)


@needs_sigrok
def test_framing_errors_become_garbage_with_their_reason(tmp_path):
    """A low stop bit: flagged by our decoder of the .sr and by sigrok-cli's 'Frame error' rows alike."""
    baud, rate = 115200, 1_000_000
    frame = bytes.fromhex("FAAF01001E020184039B")
    x = encode([(frame, 0.0), (frame, 0.002)], rate, baud, lead=LEAD)
    bit = rate / baud
    stop = int(round(LEAD * rate + (3 * 10 + 9) * bit))  # byte 3's stop bit, pulled low in its middle
    x[stop + int(bit / 4):stop + int(3 * bit / 4)] = False
    sr = sigrok_sr(tmp_path / "fe.sr", {"D0": x}, rate)
    text = tmp_path / "fe.txt"
    text.write_text(annotate(sr, "D0", baud, classes="rx-data:rx-warnings"))
    assert "Frame error" in text.read_text()
    for path in (sr, text):
        got = chunks_of(path, baud=baud)
        marked = [c for c in got if type(c) is Marked]
        assert [(c[0], c.error) for c in marked] == [(frame[3:4], FRAMING_ERROR)]
        events = events_of(got, baud)
        kinds = [(e.kind, getattr(e, "reason", None)) for e in events]
        assert ("garbage", FRAMING_ERROR) in kinds and kinds[-1] == ("short", None)


@needs_sigrok
def test_channel_by_name_and_index(capsys, tmp_path):
    baud, rate = 115200, 1_000_000
    sent = sim(baud, 1.1)
    bus = encode(sent, rate, baud, lead=LEAD)
    clock = (np.arange(len(bus)) // 500) % 2 == 0  # a 1 kHz square wave on channel 0
    sr = sigrok_sr(tmp_path / "two.sr", {"CLK": clock, "RX": bus}, rate)
    for choice in ("RX", "rx", "1"):
        got, err = jsonl(capsys, str(sr), "--channel", choice)
        assert payload([(bytes.fromhex(r["raw"]), None) for r in got]) == payload(sent), choice
    # Without --channel: the first channel that toggles, and a warning that names the others.
    got, err = jsonl(capsys, str(sr), "--baud", "115200")
    assert "channels CLK, RX all carry signals; decoding CLK" in err
    # A config file's channel, overridden by the command line.
    cfg = tmp_path / "rs30x-sniff.toml"
    cfg.write_text('channel = "RX"\n')
    assert main(["info", str(sr), "--config", str(cfg), "--format", "json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["bytes"] == len(payload(sent)) and info["settings"]["channel"] == "RX"


@pytest.mark.parametrize("choice", ["D7", "9", "TX"])
def test_an_unknown_channel_is_a_one_line_error_and_exit_2(tmp_path, choice):
    out = subprocess.run(["rs30x-sniff", "decode", str(SAMPLE), "--channel", choice, "--isolated"],
                         capture_output=True, text=True, cwd=tmp_path,
                         env={"PATH": str(Path(__import__("sys").executable).parent)})
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "Traceback" not in out.stderr
    assert f"no channel {choice!r} (the capture has D0 (index 0), D1 (index 1))" in out.stderr


def test_a_bad_channel_setting_names_the_file_and_key(tmp_path, capsys):
    cfg = tmp_path / "rs30x-sniff.toml"
    cfg.write_text("channel = -1\n")
    assert main(["decode", str(SAMPLE), "--config", str(cfg)]) == 2
    assert "channel = -1: must be a channel name or an index from 0" in capsys.readouterr().err


# ---- odd and damaged sessions ----------------------------------------------------------------------
def test_unitsize_2_and_a_channel_in_the_high_byte(tmp_path):
    baud, rate = 115200, 1_000_000
    frame = bytes.fromhex("FAAF01001E020184039B")
    x = encode([(frame, 0.0)], rate, baud, lead=LEAD)
    units = (x.astype(np.uint16) << 9) | 0x0001  # channel 9 (probe10) carries the bus; channel 0 is high
    path = hand_sr(tmp_path / "wide.sr", units.astype("<u2").tobytes(), unitsize=2,
                   probes="probe1=D0\nprobe10=D9\n")
    got = chunks_of(path, channel="D9")
    assert payload(got) == frame and abs(got[0][1] - LEAD) < 2 / rate
    assert payload(chunks_of(path, channel="9")) == frame
    assert payload(chunks_of(path)) == frame  # D0 never toggles: D9 is the one that does


def test_a_capture_that_starts_low_decodes_from_the_first_whole_byte(tmp_path):
    baud, rate = 115200, 1_000_000
    frame = bytes.fromhex("FAAF01001E020184039B")
    x = encode([(b"\x00" + frame, 0.0)], rate, baud, lead=0.0)[30:]  # starts inside the 00's low bits
    assert not x[0]
    got = chunks_of(hand_sr(tmp_path / "low.sr", x.astype(np.uint8).tobytes()), baud=baud)
    assert payload(got) == frame


def test_an_empty_session_is_an_empty_capture(tmp_path, capsys):
    for samples in (None, b""):
        path = hand_sr(tmp_path / "empty.sr", samples)
        assert chunks_of(path) == []
        assert main(["info", str(path), "--isolated"]) == 0
        assert "no data (the capture is empty)" in capsys.readouterr().err


def test_an_idle_line_that_is_low_is_warned_about(tmp_path):
    warnings: list[str] = []
    path = hand_sr(tmp_path / "low.sr", bytes(5000))
    assert list(read_capture(str(path), warn=warnings.append, options={"baud": 115200})) == []
    assert any("is low 100% of the time" in w for w in warnings)


@pytest.mark.parametrize("damage,message", [
    (lambda b: b[:len(b) // 2], "not a readable sigrok session"),
    (lambda b: b"PK\x03\x04" + b"\0" * 100, "not a readable sigrok session"),
])
def test_a_damaged_zip_is_a_one_line_error(tmp_path, damage, message):
    path = tmp_path / "bad.sr"
    path.write_bytes(damage(SAMPLE.read_bytes()))
    with pytest.raises(CaptureError, match=message) as e:
        chunks_of(path)
    assert "\n" not in str(e.value) and str(path) in str(e.value)


@pytest.mark.parametrize("kwargs,message", [
    ({"version": "9"}, "version '9' is not one this reader knows"),
    ({"metadata": "[global]\n"}, "no \\[device N\\] section"),
    ({"metadata": "[device 1]\ncapturefile=logic-1\nunitsize=1\nprobe1=D0\n"}, "gives no samplerate"),
    ({"metadata": "[device 1]\ncapturefile=logic-1\nsamplerate=fast\nprobe1=D0\n"}, "'fast' is not a rate"),
    ({"metadata": "[device 1]\ncapturefile=logic-1\nsamplerate=1 MHz\nunitsize=1\nprobe12=D11\n"}, "beyond the 8 bits"),
    ({"metadata": "no section at all"}, "not an INI file"),
])
def test_bad_metadata_is_a_one_line_error(tmp_path, kwargs, message):
    with pytest.raises(CaptureError, match=message) as e:
        chunks_of(hand_sr(tmp_path / "bad.sr", bytes(10), **kwargs))
    assert "\n" not in str(e.value)


def test_too_slow_a_sample_rate_for_the_baud_is_an_error(tmp_path):
    with pytest.raises(CaptureError, match="too slow for 921600 bit/s"):
        chunks_of(hand_sr(tmp_path / "slow.sr", bytes(10)), baud=921600)


def test_a_zip_without_extension_is_sniffed(tmp_path):
    path = tmp_path / "capture"
    path.write_bytes(SAMPLE.read_bytes())
    assert detect_format(str(path)) == "sigrok"


def test_samplerate_spellings():
    from rs30x_sniff.sources.sigrok import parse_samplerate

    assert parse_samplerate("1 MHz") == 1e6 and parse_samplerate("500 kHz") == 5e5
    assert parse_samplerate("4000000") == 4e6 and parse_samplerate("1.5 MHz") == 1.5e6
    assert parse_samplerate("24MHz") == 24e6 and parse_samplerate("0") is None and parse_samplerate("x") is None


# ---- annotation text ---------------------------------------------------------------------------------
GOOD = ["100-170 uart-1: FA", "187-257 uart-1: AF", "274-344 uart-1: 01"]


def test_annotation_forms(tmp_path):
    text = tmp_path / "a.txt"
    text.write_text('100-170 uart-1: rx-data: "FA"\n187-257 uart-1: rx-data: "AF"\n'
                    '190-200 uart-1: tx-data: "55"\n274-344 uart-1: rx-stop: "Stop bit" "Stop" "T"\n')
    assert detect_format(str(text)) == "sigrok-uart"
    assert payload(chunks_of(text, baud=115200)) == b"\xfa\xaf\x55"
    assert payload(chunks_of(text, baud=115200, channel="rx")) == b"\xfa\xaf"
    assert payload(chunks_of(text, baud=115200, channel="TX")) == b"\x55"
    plain = tmp_path / "p.txt"
    plain.write_text("uart-1: FA\nuart-1: AF\nuart-1: Frame error\nuart-1: 01\n")
    got = chunks_of(plain)
    assert payload(got) == b"\xfa\xaf\x01" and all(c[1] is None for c in got)
    assert [c.error for c in got if type(c) is Marked] == [FRAMING_ERROR]


def test_text_that_only_looks_like_annotations_is_not_sniffed():
    from rs30x_sniff.sources.sigrok import sniff_annotations

    assert sniff_annotations("\n".join(GOOD).encode())
    assert not sniff_annotations(b"FA AF 01 00\n")
    assert not sniff_annotations(b"0.5 FA AF\n")
    assert not sniff_annotations(b"100-170 i2c-1: Start\n")
    assert not sniff_annotations(b"100-170 uart-1: Start bit\n")  # no byte at all
    assert not sniff_annotations("\n".join(["hello", *GOOD]).encode())
    assert sniff_annotations("\n".join([*GOOD, "hello"]).encode())  # so the reader can name the bad line


BAD_LINES = st.one_of(
    st.sampled_from(["100-170 uart-1: ZZ", "100-170 uart-1: FAA", "100-170 uart-1: 0x12", "300-200 uart-1: FA",
                     "100-170 i2c-1: 12", "uart-1 FA", "FA AF 01", '100-170 uart-1: rx-data: FA', "100-170 uart-1: Frame failure",
                     '100-170 uart-1: rx-data: "hello"', '100-170 uart-1: xx-data: "FA"',
                     '100-170 uart-1: rx-bogus: "FA"', "100-170 uart-1: Start of something"]),
    st.text(st.characters(codec="ascii", exclude_characters="\r\n\x0b\x0c\x1c\x1d\x1e\x85"),
            min_size=1, max_size=30).filter(lambda s: s.strip() and ":" not in s),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(before=st.integers(0, 3), bad=BAD_LINES)
def test_a_bad_annotation_line_is_a_one_line_error_with_its_number(tmp_path, before, bad):
    lines = GOOD[:before] + [bad] + GOOD[before:]
    path = tmp_path / "bad.txt"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(CaptureError) as e:
        list(read_capture(str(path), "sigrok-uart", options={"baud": 115200}))
    assert e.value.line == before + 1
    assert "\n" not in str(e.value) and f"{path}:{before + 1}:" in str(e.value)


def test_a_bad_annotation_line_through_the_cli(tmp_path):
    path = tmp_path / "bad.txt"
    path.write_text("\n".join(GOOD + ["400-470 uart-1: QQ"]) + "\n")
    out = subprocess.run(["rs30x-sniff", "decode", str(path), "--baud", "115200", "--isolated"],
                         capture_output=True, text=True,
                         env={"PATH": str(Path(__import__("sys").executable).parent)})
    assert out.returncode == 2 and out.stderr.count("\n") == 1
    assert f"{path}:4: 'QQ' is neither a hex byte" in out.stderr


def test_read_input_keeps_first_byte_times():
    src = read_input(str(SAMPLE), baud=115200, options={"baud": 115200})
    assert src.time_ref.ref == "first"
    first = next(iter(src))
    assert abs(first[1] - 0.00105) < 1e-6


def test_lines_with_and_without_sample_numbers_do_not_mix(tmp_path):
    path = tmp_path / "mixed.txt"
    path.write_text("\n".join(GOOD[:2] + ["uart-1: 01"]) + "\n")
    with pytest.raises(CaptureError, match="some lines have sample numbers and some do not") as e:
        chunks_of(path, baud=115200)
    assert e.value.line == 3
