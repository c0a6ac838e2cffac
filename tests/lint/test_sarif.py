"""SARIF regions point into the file as it is written, and artifact URIs are percent-encoded."""

from __future__ import annotations

import json
from urllib.parse import unquote, urlsplit
from urllib.request import url2pathname

import jsonschema
import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.lint import Finding
from rs30x_sniff.lint.report import FileResult, sarif_log, sarif_uri

from .helpers import CAPTURES
from .test_cli import SARIF_SUBSET

EXAMPLES = CAPTURES / "manual-examples.hex"


def sarif(capsys, *argv) -> dict:
    main(["lint", *map(str, argv), "--format", "sarif"])
    log = json.loads(capsys.readouterr().out)
    jsonschema.validate(log, SARIF_SUBSET)
    return log


def results(log: dict) -> list[dict]:
    return log["runs"][0]["results"]


def test_text_capture_region_is_the_line_not_the_stream_offset(capsys, tmp_path):
    # Comments and spacing put each byte far from its stream offset in the file.
    path = tmp_path / "bench run #2.hex"
    path.write_text(EXAMPLES.read_text())
    log = sarif(capsys, path)
    lines = path.read_text().splitlines()
    assert results(log)
    for r in results(log):
        region = r["locations"][0]["physicalLocation"]["region"]
        assert "byteOffset" not in region and "byteLength" not in region
        text = lines[region["startLine"] - 1][region["startColumn"] - 1:]
        # The region starts at the first hex digit of a frame of that finding.
        assert text[:2] in ("FA", "FD", "07", "08"), (r["ruleId"], text)
        assert r["properties"]["streamOffset"] >= 0


def test_binary_capture_region_is_the_file_byte_range(capsys, tmp_path):
    data = bytes.fromhex(" ".join(line.partition("#")[0] for line in EXAMPLES.read_text().splitlines()))
    path = tmp_path / "raw dump.bin"
    path.write_bytes(data)
    log = sarif(capsys, path)
    found = results(log)
    assert {r["ruleId"] for r in found} >= {"P009", "M002"}
    for r in found:
        region = r["locations"][0]["physicalLocation"]["region"]
        assert set(region) == {"byteOffset", "byteLength"} and "startLine" not in region
        assert region["byteOffset"] == r["properties"]["streamOffset"]
    p9 = next(r for r in found if r["ruleId"] == "P009")["locations"][0]["physicalLocation"]["region"]
    assert data[p9["byteOffset"]:p9["byteOffset"] + p9["byteLength"]] == bytes.fromhex("FA AF 01 60 07 01 01 12 74")


def test_format_as_read_overrides_the_extension():
    f = Finding(offset=40, t=None, code="P009", name="combined-flash-reboot", severity="error", message="m",
                id=1, raw=b"\xfa\xaf")
    as_bin = sarif_log([FileResult("capture.dat", findings=[f], format="bin")])
    assert results(as_bin)[0]["locations"][0]["physicalLocation"]["region"] == {"byteOffset": 40, "byteLength": 2}
    # An MCAP's (or another tool's log's) stream offsets are no place in the file: no region at all.
    as_mcap = sarif_log([FileResult("capture.bin", findings=[f], format="mcap")])
    assert "region" not in results(as_mcap)[0]["locations"][0]["physicalLocation"]
    assert results(as_mcap)[0]["properties"]["streamOffset"] == 40


def test_artifact_uri_is_encoded_and_resolves_to_the_file(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my caps").mkdir()
    rel = "my caps/run #1 50%.hex"
    (tmp_path / rel).write_text(EXAMPLES.read_text())
    log = sarif(capsys, rel)
    uri = results(log)[0]["locations"][0]["physicalLocation"]["artifactLocation"]["uri"]
    assert uri == "my%20caps/run%20%231%2050%25.hex"
    assert log["runs"][0]["artifacts"] == [{"location": {"uri": uri}}]
    assert not urlsplit(uri).scheme and not urlsplit(uri).fragment and unquote(uri) == rel
    # An absolute path is a file:// URI naming the same file.
    absolute = tmp_path / rel
    uri = results(sarif(capsys, absolute))[0]["locations"][0]["physicalLocation"]["artifactLocation"]["uri"]
    parts = urlsplit(uri)
    assert parts.scheme == "file" and not parts.fragment and url2pathname(parts.path) == str(absolute)


@pytest.mark.parametrize("path, uri", [
    ("captures/a.hex", "captures/a.hex"),
    ("a:b.hex", "a%3Ab.hex"),  # would otherwise read as the scheme "a"
    ("-", "-"),
    ("socket://localhost:7777", "socket://localhost:7777"),
    ("/dev/ttyUSB0", "file:///dev/ttyUSB0"),
])
def test_sarif_uri(path, uri):
    assert sarif_uri(path) == uri
