"""The servos pane's rows: a snapshot of every servo the bus tracker knows, made on the decoding thread."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..decode.pairing import BusTracker

# Registers the servos pane shows.
SERVO_COLUMNS = ("torque_enable", "goal_position", "present_position", "present_speed", "present_current",
                 "present_temperature", "present_voltage")
LATENCY_SAMPLES = 1000  # percentiles over the most recent replies


@dataclass
class ServoRow:
    """One servo as the servos pane shows it (a snapshot made on the decoding thread)."""

    id: int
    model: str
    values: dict[str, Any]
    units: dict[str, str | None]
    requests: int
    returns: int
    latency_p50: float | None
    latency_p95: float | None
    last_t: float | None


def _percentile(sorted_values: list[float], q: float) -> float | None:
    if not sorted_values:
        return None
    k = min(len(sorted_values) - 1, max(0, round(q * (len(sorted_values) - 1))))
    return sorted_values[k]


def servo_snapshot(bus: BusTracker) -> dict[int, ServoRow]:
    """Rows for every servo the bus tracker knows; called on the thread that feeds the tracker."""
    rows: dict[int, ServoRow] = {}
    for sid, st in list(bus.servos.items()):
        values, units = {}, {}
        for name in SERVO_COLUMNS:
            try:
                reg = st.model.register(name)
            except KeyError:
                continue
            values[name] = st.get(name)
            units[name] = reg.unit
        lat = sorted(list(st.latencies)[-LATENCY_SAMPLES:])
        rows[sid] = ServoRow(sid, st.model.name, values, units, st.requests, st.returns,
                             _percentile(lat, 0.5), _percentile(lat, 0.95), st.last_t)
    return rows
