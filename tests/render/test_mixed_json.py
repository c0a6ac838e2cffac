"""A long packet to servos of mixed models: its fields' JSON from one generated fill of the whole packet
(layout_json.MixedJson) is mixed_fields_json's, record by record, on every shape such a packet takes."""

from __future__ import annotations

import random

import pytest

from rs30x_sniff.protocol.memmap import default_registry
from rs30x_sniff.protocol.wire import encode_long
from rs30x_sniff.render.layout_json import MixedJson, long_plan, mixed_fields_json

REG = default_registry()
NAMES = sorted(REG.models)


def _packets(seed: int) -> list[tuple[bytes, dict]]:
    """Long packets (whole frames) of many shapes, with a model for each VID."""
    rng = random.Random(seed)
    out = []
    for _ in range(60):
        vids = rng.sample(range(1, 30), rng.randint(1, 8))
        models = {v: REG.get(rng.choice(NAMES)) for v in vids}
        address, length = rng.randint(0, 60), rng.randint(2, 12)
        frame = encode_long(address, [(v, bytes(rng.randrange(256) for _ in range(length - 1))) for v in vids])
        if rng.random() < 0.3 and len(vids) > 1:  # the last record cut short: Length says more than the data holds
            cut = rng.randint(1, length - 1)
            body = bytearray(frame[:-1 - cut])
            body[6] = len(vids)
            s = 0
            for b in body[2:]:
                s ^= b
            frame = bytes(body) + bytes([s])
        out.append((frame, models))
    return out


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("compact", [False, True])
def test_one_fill_equals_record_by_record(seed, compact):
    compiled = 0
    for frame, models in _packets(seed):
        plan = long_plan(frame, models)
        if not isinstance(plan, tuple):  # one model for them all: a Layout of its own (fields_json)
            continue
        mixed = MixedJson(plan)
        data = frame[7:-1]
        for only in (None, {next(iter(models))}):
            assert mixed.text(data, only, compact) == mixed_fields_json(plan, data, only, compact)
        compiled += mixed.fills[compact] is not None
    assert compiled > 20
