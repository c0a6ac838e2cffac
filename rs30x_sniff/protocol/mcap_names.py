"""The names an rs30x-sniff MCAP file is written and read by: its magic, channels (topic and schema),
metadata records, time bases and log times.

The writer (rs30x_sniff.sinks.mcap), the live server (its foxglove module) and the reader
(rs30x_sniff.sources.mcap_reader) import them from here, so a reader never imports a writer.
"""

from __future__ import annotations

MCAP_MAGIC = b"\x89MCAP0\r\n"

# Channels: (topic, schema); the schemas' JSON is in rs30x_sniff/schemas.
RAW_TOPIC = "/rs30x/raw"
PACKETS_TOPIC = "/rs30x/packets"
TRANSACTIONS_TOPIC = "/rs30x/transactions"
DIAGNOSTICS_TOPIC = "/rs30x/diagnostics"
STATE_TOPIC = "/rs30x/servo/{id}/state"
RAW_SCHEMA = "rs30x.Raw"
PACKET_SCHEMA = "rs30x.Packet"
TRANSACTION_SCHEMA = "rs30x.Transaction"
SERVO_STATE_SCHEMA = "rs30x.ServoState"
LOG_SCHEMA = "foxglove.Log"
RAW_ENCODING = "json"

METADATA_NAME = "rs30x"               # written first: a killed writer still leaves it
MODELS_METADATA_NAME = "rs30x.models"  # written by finish(): what the bus taught us
STATS_METADATA_NAME = "rs30x.stats"    # written by finish(): `info`'s figures for the whole log, as JSON
GAPS_METADATA_NAME = "rs30x.gaps"      # written by finish() if the port was lost and found again: the gaps, as JSON
# The rs30x metadata's "topics": what a file holds beside its raw bytes, findings and figures. A raw file (record's
# default) is decoded again by whoever reads it; `convert` writes its decoded topics.
TOPICS_RAW = "raw"
GAP_METADATA_NAME = "rs30x.gap"        # one gap, written when the port came back (a cut file keeps it): JSON values

# capture: the capture's own times; synthetic: byte positions at the baud rate (no timestamps);
# wall: a live port, in wall-clock time; monotonic: older live logs, seconds since the port opened.
TIME_BASES = ("capture", "synthetic", "wall", "monotonic")


def log_time_ns(t: float) -> int:
    """A time in seconds as a message's log time: whole nanoseconds, never negative."""
    return int(round(t * 1e9)) if t > 0 else 0
