"""Start-up (issue 35): a command line imports its own command's module only, `--help` loads no numpy, the BLAS
pool is told to keep to one thread unless the user said otherwise, and the parser a command line gets says the
same as the whole parser."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from rs30x_sniff import cli

PROBE = """
import json, os, sys
from rs30x_sniff.cli import main
code = main(sys.argv[1:])
print(json.dumps({"code": code, "modules": sorted(m for m in sys.modules if m.startswith(("numpy", "rs30x_sniff"))),
                  "blas": os.environ.get("OPENBLAS_NUM_THREADS")}))
"""


def probe(*argv: str, env: dict[str, str] | None = None) -> dict:
    """What a fresh process running ``rs30x-sniff ARGV`` has imported (its last stdout line)."""
    environ = {k: v for k, v in os.environ.items() if k not in cli.ONE_THREAD}
    out = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, check=True,
                         env={**environ, **(env or {})}).stdout
    return json.loads(out.splitlines()[-1])


def commands_imported(modules: list[str]) -> set[str]:
    return {m.removeprefix("rs30x_sniff.commands.") for m in modules} & set(cli.COMMANDS)


@pytest.mark.parametrize("argv", [["--help"], ["--version"], [], ["nosuch"]])
def test_the_top_level_imports_no_command_and_no_numpy(argv):
    got = probe(*argv)
    assert got["code"] in (0, 2)
    assert not commands_imported(got["modules"])
    assert not [m for m in got["modules"] if m.split(".")[0] == "numpy"]


@pytest.mark.parametrize("command", ["lint", "rules", "simulate", "table"])
def test_a_command_imports_its_own_module_only(command):
    got = probe(command, "--help")
    assert got["code"] == 0
    assert commands_imported(got["modules"]) == {command}


def test_the_blas_pool_keeps_to_one_thread_unless_the_user_set_it():
    assert probe("info", "--help")["blas"] == "1"
    assert probe("info", "--help", env={"OPENBLAS_NUM_THREADS": "4"})["blas"] == "4"


def test_the_top_level_help_is_the_whole_parsers():
    whole = cli.build_parser()
    for argv in ([], ["--help"], ["lint", "x.bin"]):
        assert cli.build_parser(argv).format_help() == whole.format_help()


@pytest.mark.parametrize("command", cli.COMMANDS)
def test_each_command_says_what_the_whole_parser_says(command):
    whole = cli.build_parser().commands[command]
    alone = cli.build_parser([command]).commands[command]
    assert alone.format_help() == whole.format_help()
    assert alone.numbers == whole.numbers  # the same options bounded by OPTION_MAX
    assert alone.format_usage() == whole.format_usage()


def test_the_chosen_command_is_the_first_word_that_is_no_option():
    assert cli.chosen_command(["--version", "lint", "decode"]) == "lint"
    assert cli.chosen_command(["-h"]) is None
    assert cli.chosen_command(["lnt", "lint"]) is None  # a typo is argparse's error, with every choice listed
    assert cli.chosen_command(cli.aliased(["export", "--table", "states", "x.bin"])) == "table"


def test_an_unknown_command_lists_every_choice(capsys):
    assert cli.main(["lnt"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(cli.ERROR) and all(f"'{name}'" in err for name in cli.COMMANDS)


def test_plugin_loads_no_numpy(tmp_path):
    # The plug-ins are made from the memory maps alone (issue 35: `plugin` does not need numpy).
    for argv in (["plugin", "--help"], ["plugin", "sigrok", "-o", str(tmp_path / "out")]):
        got = probe(*argv)
        assert got["code"] == 0, argv
        assert not [m for m in got["modules"] if m.split(".")[0] == "numpy"], argv
    assert (tmp_path / "out").is_dir()
