"""A raw recording (record's default, McapSink(decoded=False)): the bytes, findings and figures only, and every
command reads it as it reads a decoded one; convert writes its decoded topics."""

from __future__ import annotations

import json
from collections import Counter

import pytest
from mcap.reader import make_reader

from rs30x_sniff.cli import main
from rs30x_sniff.lint import Linter
from rs30x_sniff.sim import run

from .conftest import to_mcap


def topics(path) -> Counter:
    with open(path, "rb") as f:
        return Counter(ch.topic for _, ch, _ in make_reader(f).iter_messages())


def metadata(path) -> dict:
    with open(path, "rb") as f:
        return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """The overheat scenario (findings, flags) recorded raw and decoded, a gather-like chunking as a port gives."""
    d = tmp_path_factory.mktemp("raw")
    chunks = list(run("overheat", duration=3.0, seed=2))
    paths = {}
    for decoded in (False, True):
        path = d / f"{'all' if decoded else 'raw'}.mcap"
        to_mcap(chunks, path, linter=Linter(), decoded=decoded)
        paths[decoded] = path
    return paths


def test_a_raw_recording_holds_the_bytes_findings_and_figures_only(recordings):
    raw, full = topics(recordings[False]), topics(recordings[True])
    assert set(raw) == {"/rs30x/raw", "/rs30x/diagnostics"}
    assert raw["/rs30x/raw"] == full["/rs30x/raw"] and raw["/rs30x/diagnostics"] == full["/rs30x/diagnostics"] > 0
    meta_raw, meta_full = metadata(recordings[False]), metadata(recordings[True])
    assert meta_raw["rs30x"]["topics"] == "raw" and "topics" not in meta_full["rs30x"]
    assert json.loads(meta_raw["rs30x.stats"]["stats"]) == json.loads(meta_full["rs30x.stats"]["stats"])


@pytest.mark.parametrize("command", [["decode", "--format", "jsonl"], ["lint", "--format", "json"],
                                     ["info", "--format", "json"]])
def test_every_command_reads_a_raw_recording_as_a_decoded_one(recordings, command, capsys):
    outs = []
    for decoded in (False, True):
        code = main([*command, str(recordings[decoded])])
        out = capsys.readouterr().out
        outs.append(out.replace(str(recordings[decoded]), "FILE"))
        assert code in (0, 1)
    assert outs[0] == outs[1]


def test_convert_writes_the_decoded_topics_of_a_raw_recording(recordings, tmp_path, capsys):
    out = tmp_path / "full.mcap"
    assert main(["convert", str(recordings[False]), "-o", str(out)]) in (0, 1)
    capsys.readouterr()
    assert topics(out) == topics(recordings[True])
