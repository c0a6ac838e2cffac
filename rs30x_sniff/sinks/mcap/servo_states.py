"""Which servos' registers a decoded record changes: the one rule the MCAP state channel and the states table share."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ...protocol.events import Garbage
from ...protocol.wire import BROADCAST_ID, LONG_PACKET_ID

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ...decode.pairing import Record


class ServoStates:
    """Follows the servos a stream of records talks about: each one's model, and what a record sets.

    Only intact requests and returns change a servo's state (a corrupt packet's values cannot be
    trusted); a broadcast write applies to every servo already known.
    """

    def __init__(self, models: dict[int, str] | None = None) -> None:
        self.models: dict[int, str] = dict(models or {})  # servo -> the model name its records used
        self.known: dict[int, None] = {}                  # servos with a state, in the order first seen

    def changes(self, rec: Record) -> dict[int, list[tuple[str, Any]]]:
        """``{servo: [(register name, value), ...]}`` for every servo whose registers ``rec`` sets."""
        ev = rec.event
        if type(ev) is Garbage:
            return {}
        sid = rec.id
        if sid is not None and sid != LONG_PACKET_ID and sid != BROADCAST_ID and rec.model is not None:
            self.models[sid] = rec.model.name
        if not (ev.checksum_ok and (rec.is_request or ev.kind == "return")):
            return {}
        out: dict[int, list[tuple[str, Any]]] = {}
        known = self.known
        for fid, name, value in rec.named_values():
            for tid in (list(known) if fid == BROADCAST_ID else (fid,)):
                pairs = out.get(tid)
                if pairs is None:
                    pairs = out[tid] = []
                    known[tid] = None
                pairs.append((name, value))
        return out
