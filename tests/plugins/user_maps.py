"""Memory maps a user puts on $RS30X_DECODERS, for the plug-in tests: a hostile model and a renamed register."""

from __future__ import annotations

import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TORQUE_ENUM = 'enum = { 0 = "off", 1 = "on", 2 = "brake" }'
TORQUE_DOC = 'description = "Torque off, on, or brake mode"'


def toml_string(text: str) -> str:
    return json.dumps(text)  # a JSON string is a TOML basic string


def write_user_maps(folder: Path, labels: dict[str, str], description: str,
                    edit=lambda text: text) -> None:
    """In ``folder``: EVIL1 (RS303MR's map, model number 0x7E71) whose torque_enable labels are ``labels`` (by the
    bundled label: off, on, brake) and whose description is ``description`` (then ``edit`` of its text); and an
    RS303MR whose present_temperature is renamed case_temperature."""
    bundled = (ROOT / "decoders" / "rs303mr.toml").read_text()
    hostile = bundled.replace('name = "RS303MR"', 'name = "EVIL1"').replace("model_number = 0x3030",
                                                                             "model_number = 0x7E71")
    enum = "enum = { " + ", ".join(f"{k} = {toml_string(labels[v])}" for k, v in
                                   ((0, "off"), (1, "on"), (2, "brake"))) + " }"
    assert TORQUE_ENUM in hostile and TORQUE_DOC in hostile
    hostile = hostile.replace(TORQUE_ENUM, enum).replace(TORQUE_DOC, f"description = {toml_string(description)}")
    (folder / "evil1.toml").write_text(edit(hostile))
    renamed = bundled.replace('name = "present_temperature"', 'name = "case_temperature"')
    assert renamed != bundled
    (folder / "rs303mr.toml").write_text(renamed)
