"""`convert -o OUT.pcapng`: every byte in one packet, in order; times in ns; directions; findings as comments;
the file opens in tshark and capinfos without our plug-in; convert's output rules."""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
from datetime import datetime
from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.sources.captures import read_capture
from tests.conftest import CAPTURES

TSHARK = shutil.which("tshark")
CAPINFOS = shutil.which("capinfos")
needs_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
needs_capinfos = pytest.mark.skipif(CAPINFOS is None, reason="capinfos is not installed (apt-get install tshark)")

BYTE_SECONDS = 10 / 115200  # one byte at 115200 bit/s, 8N1 (start, 8 data bits, stop)
INBOUND, OUTBOUND, UNKNOWN = 1, 2, 0
DIRECTION = {"short": OUTBOUND, "long": OUTBOUND, "return": INBOUND, "ack": INBOUND, "nack": INBOUND,
             "garbage": UNKNOWN}


# ---- a reader of pcapng written for these tests (the spec, not the writer) -------------------------------
def read_options(body: bytes) -> list[tuple[int, bytes]]:
    out, k = [], 0
    while k + 4 <= len(body):
        code, n = struct.unpack_from("<HH", body, k)
        if code == 0:
            break
        out.append((code, body[k + 4:k + 4 + n]))
        k += 4 + n + (-n % 4)
    return out


def read_pcapng(path: Path) -> dict:
    data = path.read_bytes()
    out: dict = {"packets": [], "isb": None}
    k = 0
    while k < len(data):
        kind, total = struct.unpack_from("<II", data, k)
        assert total % 4 == 0 and struct.unpack_from("<I", data, k + total - 4)[0] == total
        body = data[k + 8:k + total - 4]
        if kind == 0x0A0D0D0A:
            magic, major, minor, _ = struct.unpack_from("<IHHq", body)
            assert (magic, major, minor) == (0x1A2B3C4D, 1, 0)
            out["shb"] = read_options(body[16:])
        elif kind == 1:
            out["linktype"], _, out["snaplen"] = struct.unpack_from("<HHI", body)
            out["idb"] = read_options(body[8:])
        elif kind == 6:
            iface, hi, lo, cap, orig = struct.unpack_from("<IIIII", body)
            assert iface == 0 and cap == orig
            pdu = body[20:20 + cap]
            out["packets"].append({"ns": hi << 32 | lo, "pdu": pdu, "options": read_options(body[20 + cap + (-cap % 4):])})
        elif kind == 5:
            out["isb"] = read_options(body[12:])
        else:
            raise AssertionError(f"block type {kind:#x}")
        k += total
    return out


def payload(pdu: bytes) -> tuple[bytes, dict]:
    """(the wire's bytes, the rs30x header) of a packet: after the exported-PDU tags and the rs30x header."""
    k = 0
    tags = {}
    while True:
        tag, n = struct.unpack_from(">HH", pdu, k)
        k += 4
        if tag == 0:
            break
        tags[tag] = pdu[k:k + n]
        k += n
    assert tags[12].rstrip(b"\0") == b"rs30x"  # EXP_PDU_TAG_DISSECTOR_NAME
    version, kind, direction, rlen, request, mlen = struct.unpack_from(">BBBBIB", pdu, k)
    k += 9
    reason, model = pdu[k:k + rlen].decode(), pdu[k + rlen:k + rlen + mlen].decode()
    k += rlen + mlen
    return pdu[k:], {"version": version, "kind": kind, "direction": direction, "request": request,
                     "reason": reason, "model": model}


def comments(opts: list[tuple[int, bytes]]) -> list[str]:
    return [v.decode("utf-8") for c, v in opts if c == 1]


# ---- inputs ------------------------------------------------------------------------------------------
def bundled() -> list[Path]:
    return [*sorted(CAPTURES.glob("*.hex")), *sorted(CAPTURES.glob("*.thex")), *sorted((CAPTURES / "lint").iterdir())]


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    """path -> (pcapng, decode's records, decode's end-of-input diagnostics) of every bundled capture."""
    tmp = tmp_path_factory.mktemp("pcapng")
    out = {}
    for k, path in enumerate(bundled()):
        pcapng, jsonl = tmp / f"{k}.pcapng", tmp / f"{k}.jsonl"
        assert main(["convert", str(path), "-o", str(pcapng), "--isolated"]) == 0
        assert main(["decode", str(path), "--format", "jsonl", "-o", str(jsonl), "--isolated"]) == 0
        lines = [json.loads(line) for line in jsonl.read_text().splitlines()]
        # A diagnostic line before a record is a finding between records (F010 at a seam): a comment on that
        # record's packet, as on its own findings; those after the last record came at the end of input.
        records, before = [], []
        for x in lines:
            if x["type"] == "diagnostic":
                before.append(x)
            else:
                records.append({**x, "diagnostics": before + x["diagnostics"]})
                before = []
        out[path] = (pcapng, records, before)
    return out


def test_every_byte_is_in_one_packet_in_order_with_its_kind_direction_and_time(converted):
    for path, (pcapng, records, _) in converted.items():
        f = read_pcapng(pcapng)
        assert f["linktype"] == 252
        assert len(f["packets"]) == len(records), path
        wire = b"".join(data for data, _ in read_capture(str(path), warn=lambda _m: None))
        got = [payload(p["pdu"]) for p in f["packets"]]
        assert b"".join(raw for raw, _ in got) == wire, path
        for k, (p, (raw, head), rec) in enumerate(zip(f["packets"], got, records)):
            assert raw.hex() == rec["raw"]
            assert head["direction"] == DIRECTION[rec["type"]]
            flags = [struct.unpack("<I", v)[0] for c, v in p["options"] if c == 2]  # epb_flags
            assert flags == [DIRECTION[rec["type"]]]
            seconds = rec["t"] if rec["t"] is not None else rec["offset"] * BYTE_SECONDS
            assert p["ns"] == round(seconds * 1e9), (path, k)
            assert head["reason"] == (rec["reason"] if rec["type"] == "garbage" else "")
            assert head["model"] == (rec["model"] or "")


def test_findings_are_comments_on_their_packets_and_late_ones_on_the_statistics(converted):
    late_seen = 0
    for path, (pcapng, records, late) in converted.items():
        f = read_pcapng(pcapng)
        for p, rec in zip(f["packets"], records):
            assert comments(p["options"]) == [f"{d['code']} {d['name']}: {d['message']}" for d in rec["diagnostics"]]
        frame_of = {r["offset"]: k + 1 for k, r in enumerate(records)}
        assert comments(f["isb"]) == [f"frame {frame_of[d['offset']]} (offset {d['offset']}): {d['code']} {d['name']}: {d['message']}"
                       for d in late], path
        late_seen += len(late)
    assert late_seen >= 3
    f001 = converted[CAPTURES / "lint" / "F001-checksum-mismatch.hex"]
    assert any(c.startswith("F001 checksum-mismatch: ") for p in read_pcapng(f001[0])["packets"]
               for c in comments(p["options"]))


def test_a_reply_names_the_frame_of_its_request(converted):
    pcapng, records, _ = converted[CAPTURES / "manual-examples.hex"]
    frame_of = {r["offset"]: k + 1 for k, r in enumerate(records)}
    heads = [payload(p["pdu"])[1] for p in read_pcapng(pcapng)["packets"]]
    assert [h["request"] for h in heads] == [frame_of[r["reply_to"]] if r["reply_to"] is not None else 0
                                             for r in records]
    assert any(h["request"] for h in heads)


def test_the_interface_says_the_rate_and_an_untimed_capture_says_its_times_are_made(converted):
    f = read_pcapng(converted[CAPTURES / "manual-examples.hex"][0])
    idb = dict(f["idb"])
    assert idb[2] == b"rs30x" and idb[3] == b"RS30x bus, 115200 bit/s 8N1" and idb[9] == bytes([9])
    assert "no times" in idb[1].decode() and "115200 bit/s" in idb[1].decode()
    timed = read_pcapng(converted[CAPTURES / "session-mixed.thex"][0])
    assert "no times" not in dict(timed["idb"])[1].decode()


def test_a_wall_clock_anchor_gives_absolute_times(tmp_path):
    out = tmp_path / "x.pcapng"
    path = CAPTURES / "manual-examples.hex"
    assert main(["convert", str(path), "-o", str(out), "--start-time", "2026-11-22T15:30:00Z", "--isolated"]) == 0
    start = datetime.fromisoformat("2026-11-22T15:30:00+00:00").timestamp()
    packets = read_pcapng(out)["packets"]
    assert packets[0]["ns"] == round(start * 1e9)
    assert packets[1]["ns"] - packets[0]["ns"] == round(len(payload(packets[0]["pdu"])[0]) * BYTE_SECONDS * 1e9)


# ---- other tools, without our plug-in -----------------------------------------------------------------
@needs_tshark
def test_tshark_without_the_plugin_opens_it_as_exported_pdus_naming_rs30x(converted):
    pcapng, records, _ = converted[CAPTURES / "lint" / "F001-checksum-mismatch.hex"]
    run = subprocess.run([TSHARK, "-n", "-r", str(pcapng), "-T", "fields", "-e", "frame.protocols",
                          "-e", "exported_pdu.prot_name", "-e", "frame.p2p_dir", "-e", "frame.comment"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    rows = [line.split("\t") for line in run.stdout.splitlines()]
    assert len(rows) == len(records)
    assert {r[0] for r in rows} == {"exported_pdu"} and {r[1] for r in rows} == {"rs30x"}
    assert [r[2] for r in rows] == ["0" if rec["type"] in ("short", "long") else "1" for rec in records]  # sent/recv
    assert [r[3] for r in rows] == [",".join(f"{d['code']} {d['name']}: {d['message']}" for d in rec["diagnostics"])
                                    for rec in records]
    assert any(r[3].startswith("F001 ") for r in rows)


@needs_capinfos
def test_capinfos_accepts_it(converted):
    pcapng, records, _ = converted[CAPTURES / "session-mixed.thex"]
    run = subprocess.run([CAPINFOS, str(pcapng)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    info = dict((k.strip(), v.strip()) for k, v in (line.split(":", 1) for line in run.stdout.splitlines()
                                                     if ":" in line))
    assert info["File encapsulation"] == "Wireshark Upper PDU export"
    assert info["File timestamp precision"].startswith("nanoseconds")
    assert int(info["Number of packets"]) == len(records)


# ---- convert's output rules -----------------------------------------------------------------------------
def test_an_existing_file_is_replaced_only_with_force(tmp_path):
    out = tmp_path / "x.pcapng"
    out.write_bytes(b"keep")
    path = str(CAPTURES / "manual-examples.hex")
    assert main(["convert", path, "-o", str(out), "--isolated"]) == 2
    assert out.read_bytes() == b"keep"
    assert main(["convert", path, "-o", str(out), "--force", "--isolated"]) == 0
    assert read_pcapng(out)["packets"]


def test_a_failed_run_leaves_nothing(tmp_path):
    bad = tmp_path / "bad.hex"
    bad.write_text((CAPTURES / "manual-examples.hex").read_text() + "\nZZ not hex\n")
    out = tmp_path / "x.pcapng"
    assert main(["convert", str(bad), "-o", str(out), "--isolated"]) == 2
    assert os.listdir(tmp_path) == ["bad.hex"]
    empty = tmp_path / "empty.hex"
    empty.write_text("")
    assert main(["convert", str(empty), "-o", str(out), "--isolated"]) == 2
    assert not out.exists()


def test_stdout_takes_the_same_file_given_to_pcapng(tmp_path):
    path = str(CAPTURES / "manual-examples.hex")
    out = tmp_path / "x.pcapng"
    assert main(["convert", path, "-o", str(out), "--isolated"]) == 0
    run = subprocess.run([sys.executable, "-m", "rs30x_sniff", "convert", path, "-o", "-", "--to", "pcapng",
                          "--isolated"], capture_output=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout == out.read_bytes()


def test_without_to_a_name_not_ending_pcapng_is_still_mcap(tmp_path):
    out = tmp_path / "x.mcap"
    assert main(["convert", str(CAPTURES / "manual-examples.hex"), "-o", str(out), "--isolated"]) == 0
    assert out.read_bytes()[:8] == b"\x89MCAP0\r\n"
