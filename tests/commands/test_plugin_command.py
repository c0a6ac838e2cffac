"""`rs30x-sniff plugin TOOL -o DIR`: the folder is written whole or not at all, and never replaced without --force."""

from __future__ import annotations

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.commands import plugin


@pytest.mark.parametrize("tool", sorted(plugin.TOOLS))
def test_each_tool_writes_its_folder_and_says_where_to_install_it(tmp_path, capsys, tool):
    out = tmp_path / "p"
    assert main(["plugin", tool, "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    files = [p for p in out.rglob("*") if p.is_file()]
    assert files and all(p.stat().st_size for p in files)
    assert str(out) in printed
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".p.")]  # no temporary folder left


def test_an_existing_folder_needs_force_and_is_then_replaced_whole(tmp_path, capsys):
    out = tmp_path / "p"
    out.mkdir()
    (out / "mine.txt").write_text("keep me")
    assert main(["plugin", "wireshark", "-o", str(out)]) == 2
    assert "already exists (use --force" in capsys.readouterr().err
    assert (out / "mine.txt").read_text() == "keep me"
    assert main(["plugin", "wireshark", "-o", str(out), "--force"]) == 0
    assert not (out / "mine.txt").exists() and (out / "rs30x.lua").exists()


def test_a_file_in_the_way_or_stdout_is_one_line_and_nothing_written(tmp_path, capsys):
    f = tmp_path / "p"
    f.write_text("a file")
    assert main(["plugin", "sigrok", "-o", str(f), "--force"]) == 2
    assert main(["plugin", "sigrok", "-o", "-"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "not a folder" in err[0] and "a plug-in is a folder" in err[1]
    assert f.read_text() == "a file"


def test_a_failed_write_leaves_the_old_folder_in_place(tmp_path, capsys, monkeypatch):
    out = tmp_path / "p"
    out.mkdir()
    (out / "old.lua").write_text("old")

    def broken(maps):
        return {"ok.txt": "x", "../escape.txt": "y"}  # a path outside the folder: refused as it is written

    monkeypatch.setattr(plugin.generator("wireshark"), "generate", broken)
    with pytest.raises(ValueError):
        main(["plugin", "wireshark", "-o", str(out), "--force"])
    assert (out / "old.lua").read_text() == "old" and not (tmp_path / "escape.txt").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["p"]
