"""The fuzz targets, run without atheris: their seed corpus, seeded random mutations and hypothesis inputs."""

from __future__ import annotations

import importlib.util
import random
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from .targets import TARGETS, seeds

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module", params=sorted(TARGETS))
def target(request):
    return request.param, TARGETS[request.param], seeds(request.param)


def _mutate(rng: random.Random, data: bytes) -> bytes:
    """One of libFuzzer's simple moves: flip, overwrite, insert, delete or cut."""
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        move = rng.randrange(5)
        i = rng.randrange(len(b) + 1)
        if move == 0 and b and i < len(b):
            b[i] ^= 1 << rng.randrange(8)
        elif move == 1 and b and i < len(b):
            b[i] = rng.choice(b"\x00\xff\n #.-0123456789aFEfnix\xfa\xaf\xfd\xdf\xef\xbb\xbf\xc2\xb0")
        elif move == 2:
            b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 8)))
        elif move == 3:
            del b[i:i + rng.randint(1, 16)]
        else:
            del b[i:]
    return bytes(b)


def test_seeds_pass(target):
    name, check, corpus = target
    assert corpus, f"no seeds for {name}"
    for content in corpus.values():
        check(content)


def test_random_mutations_of_the_seeds(target):
    name, check, corpus = target
    rng = random.Random(f"rs30x-{name}")
    items = sorted(corpus.items())
    n = 150 if name == "mcap" else 300
    for k in range(n):
        _, content = items[k % len(items)]
        if name in ("hex", "timestamped"):
            content = content[: rng.randrange(64, 1500)]  # short inputs: more of them
        check(_mutate(rng, content))


_token = st.one_of(
    st.integers(0, 255).map(lambda b: b"%02X" % b),
    st.sampled_from([b"0.5", b"10", b"1e-3", b"nan", b"-1", b"inf", b"FAAF", b"ZZ", b"0", b"1.", b".5", b"+2"]),
    st.binary(min_size=1, max_size=3),
)
_line = st.tuples(st.lists(_token, max_size=6), st.sampled_from([b" ", b"\t", b"  "]),
                  st.sampled_from([b"", b"# c", b"# 90\xc2\xb0", b"#\xff"]), st.sampled_from([b"\n", b"\r\n", b""]))
_text = st.tuples(st.booleans(), st.lists(_line, max_size=8)).map(
    lambda bt: (b"\xef\xbb\xbf" if bt[0] else b"") + b"".join(
        sp.join(toks) + (sp + c if c else b"") + eol for toks, sp, c, eol in bt[1]))


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.one_of(_text, st.binary(max_size=300)))
def test_hypothesis_text_and_bytes(data):
    for name in ("bin", "hex", "timestamped", "decoder"):
        TARGETS[name](data)


@settings(max_examples=100, deadline=None)
@given(data=st.binary(max_size=200), cut=st.integers(0, 4000), flips=st.lists(st.integers(0, 4000), max_size=3))
def test_hypothesis_mcap(data, cut, flips):
    base = bytearray(next(iter(seeds("mcap").values())))
    for f in flips:
        if f < len(base):
            base[f] ^= 0xFF
    TARGETS["mcap"](bytes(base[:cut]) + data)
    TARGETS["mcap"](b"\x89MCAP0\r\n" + data)


@pytest.mark.skipif(importlib.util.find_spec("atheris") is None,
                    reason="atheris is not installed (pip install -e '.[fuzz]'): only the pure-Python part ran")
def test_each_atheris_target_runs(tmp_path):
    # A short run of every script, from its seed corpus, so the harness itself cannot rot.
    for name in sorted(TARGETS):
        corpus = tmp_path / name
        from .targets import write_seeds
        write_seeds(name, corpus)
        proc = subprocess.run([sys.executable, str(HERE / f"fuzz_{name}.py"), "-runs=300", "-timeout=20",
                               "-print_final_stats=1", str(corpus)],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert "stat::number_of_executed_units" in proc.stderr
