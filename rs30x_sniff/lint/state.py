"""What the linter remembers: per-servo shadow registers, and write plans compiled per (model, address, length)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..protocol.codegen import attribute_setter
from ..protocol.memmap import Model

# Registers the sequence rules follow, and the Shadow attribute each one lands in.
_TRACKED = {
    "goal_position": "pos", "present_position": "pos", "goal_time": "goal_time", "torque_enable": "torque",
    "cw_angle_limit": "cw", "ccw_angle_limit": "ccw", "reverse": "reverse", "return_delay": "return_delay",
    "baud_rate": "baud",
}


class Shadow:
    """The few registers of one servo the rules need; None while unknown."""

    __slots__ = ("torque", "pos", "goal_time", "cw", "ccw", "reverse", "return_delay", "baud", "temp_limit", "flags")

    def __init__(self) -> None:
        self.torque: int | None = None
        self.pos: int | None = None        # raw 0.1 deg: the last goal sent or position reported
        self.goal_time: int | None = None
        self.cw: int | None = None
        self.ccw: int | None = None
        self.reverse: int | None = None
        self.return_delay: int | None = None
        self.baud: int | None = None       # baud_rate code in RAM (written or read), applied or not
        self.temp_limit = False            # a return said the temperature limit tripped, no reboot since
        self.flags = 0                     # status flags of the last return

    def reboot(self) -> None:
        # RAM goes back to its defaults (table 4.9): torque off; the temperature lock clears.
        self.torque = 0
        self.temp_limit = False


class Plan:
    """How a write (or read) of ``n`` bytes at ``address`` meets a model's memory map, worked out once.

    ``unpack(data)`` gives one raw integer per part (a whole register, or one byte of a 2-byte one);
    ``index`` maps register names written whole to their place in that tuple.
    """

    __slots__ = ("model", "address", "n", "parts", "index", "read_only", "reserved", "partial", "ranged",
                 "tracked", "unpack", "target_checks", "apply", "id_part", "id_range")

    def __init__(self, model: Model, address: int, n: int) -> None:
        self.model, self.address, self.n = model, address, n
        # The memory map's own layout of these bytes (whole registers, or one byte of a 2-byte one).
        layout = model.layout(address, n)
        parts = [(reg, partial) for _, _, reg, partial in layout.parts]
        self.parts = tuple(parts)
        self.unpack = layout.unpack_raw
        self.index = {reg.name: j for j, (reg, p) in enumerate(parts) if reg.name and not p}
        seen: set[str] = set()
        ro: list[str | None] = []
        res: list[str] = []
        part: list[str] = []
        ranged: list[tuple[int, str | None, Any, Any]] = []
        named = [j for j, (reg, _) in enumerate(parts) if reg.name]
        for j, (reg, p) in enumerate(parts):
            if reg.name is None:
                # A reserved byte between two registers of the same write is carried along (the manual
                # itself writes 30-36 across reserved 34); only the ends of a write are suspicious.
                bridged = named and named[0] < j < named[-1]
                if reg.label not in seen and not bridged:
                    res.append(reg.label)
            elif reg.access == "read":
                if reg.name not in seen:
                    ro.append(reg.name)
            elif p and reg.name not in seen:
                part.append(f"{reg.name} ({p} byte)")
            if not p and reg.range is not None and reg.access == "read-write":
                ranged.append((j, reg.name, reg.range[0], reg.range[1]))
            seen.add(reg.label)
        self.read_only, self.reserved, self.partial = tuple(ro), tuple(res), tuple(part)
        self.ranged = tuple(ranged)
        self.tracked = tuple((attr, self.index[name]) for name, attr in _TRACKED.items() if name in self.index)
        # A write of servo_id moves the servo to its new ID at once (table 4.6 No. 4), if in range (1-127).
        self.id_part = self.index.get("servo_id")
        self.id_range = (1, 127) if self.id_part is None else (parts[self.id_part][0].range or (1, 127))
        # apply(shadow, raws): store the tracked registers (setattr of each of tracked), generated once per
        # plan as it runs per servo written (protocol.codegen; the attributes are Shadow's, from _TRACKED).
        self.apply = attribute_setter(self.tracked)
        self.target_checks: tuple[Callable[..., Any], ...] = ()  # filled by the linter: the target rules it wakes

    def unpack_long(self, count: int):
        """An unpacker for ``count`` records of VID + these bytes (one call for a whole long packet)."""
        return self.model.long_layout(self.address, self.n + 1, count).unpack_raw
