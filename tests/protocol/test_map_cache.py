"""Memory maps kept checked in the user's cache: the same models, re-read when a map changes, never a broken one."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import pytest

from rs30x_sniff.protocol import map_cache
from rs30x_sniff.protocol.memmap import ModelError, load_model, parse_model

ROOT = Path(__file__).resolve().parents[2]
MAPS = sorted((ROOT / "decoders").glob("*.toml"))


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path / "cache" / "rs30x-sniff" / "maps"


def _fields(model) -> dict:
    """What a model holds, comparable (its generated functions are new objects each time it is built)."""
    return {f.name: "fn" if callable(v := getattr(model, f.name)) else repr(v) for f in dataclasses.fields(model)}


@pytest.mark.parametrize("path", MAPS, ids=lambda p: p.stem)
def test_a_kept_map_is_the_model_its_file_gives(cache, monkeypatch, path):
    built = parse_model(tomllib.loads(path.read_text(encoding="utf-8")), str(path))
    first = load_model(path)
    assert len(list(cache.glob("*.marshal"))) == 1

    def no_toml(*_args, **_kwargs):
        raise AssertionError("the kept map was parsed again")

    monkeypatch.setattr(tomllib, "loads", no_toml)
    again = load_model(path)
    assert _fields(first) == _fields(again) == _fields(built)


def test_an_edited_map_is_read_anew(cache, tmp_path):
    path = tmp_path / "rs303mr.toml"
    text = (ROOT / "decoders" / "rs303mr.toml").read_text(encoding="utf-8")
    path.write_text(text, encoding="utf-8")
    assert load_model(path).register("goal_position").name == "goal_position"
    path.write_text(text.replace('name = "goal_position"', 'name = "goal_angle"'), encoding="utf-8")
    assert load_model(path).register("goal_angle").address == 30
    assert len(list(cache.glob("*.marshal"))) == 2


def test_a_broken_map_is_never_kept(cache, tmp_path):
    path = tmp_path / "bad.toml"
    text = (ROOT / "decoders" / "rs303mr.toml").read_text(encoding="utf-8")
    path.write_text(text.replace("[model]", "[model]\nbogus = 1", 1), encoding="utf-8")
    for _ in range(2):
        with pytest.raises(ModelError, match="bogus"):
            load_model(path)
    assert not cache.exists() or not list(cache.glob("*.marshal"))


def test_a_damaged_or_unwritable_cache_is_a_miss(cache, monkeypatch, tmp_path):
    path = MAPS[0]
    want = _fields(load_model(path))
    (kept,) = cache.glob("*.marshal")
    kept.write_bytes(b"\x00garbage")
    assert _fields(load_model(path)) == want
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))  # a directory cannot be made there
    assert _fields(load_model(path)) == want
    assert map_cache.get(path.read_bytes()) is None


def test_a_map_that_is_not_utf8_is_one_line(cache, tmp_path):
    path = tmp_path / "latin.toml"
    path.write_bytes(b'[model]\nname = "caf\xe9"\n')
    with pytest.raises(ModelError, match="not UTF-8"):
        load_model(path)


def test_a_kept_map_whose_names_fail_is_read_and_checked_anew(cache, tmp_path):
    """The names become code: a kept document that says otherwise than its file (a cache written by hand) is not
    taken; the file is read and checked whole."""
    import marshal

    path = tmp_path / "rs303mr.toml"
    path.write_bytes((ROOT / "decoders" / "rs303mr.toml").read_bytes())
    want = _fields(load_model(path))
    (kept,) = cache.glob("*.marshal")
    doc = marshal.loads(kept.read_bytes())
    doc["register"][0]["name"] = "x'); import os; ('"
    kept.write_bytes(marshal.dumps(doc))
    assert _fields(load_model(path)) == want
