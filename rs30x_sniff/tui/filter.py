"""The monitor's filter language: the core one of :mod:`rs30x_sniff.filters`, which ``decode --filter`` shares."""

from __future__ import annotations

from ..filters import (EVENT_KINDS, KEYS, OP_KINDS, SEVERITIES, SEVERITY_RANK, Filter, FilterError, Predicate,
                       parse_filter, record_text)

__all__ = ["EVENT_KINDS", "KEYS", "OP_KINDS", "SEVERITIES", "SEVERITY_RANK", "Filter", "FilterError", "Predicate",
           "parse_filter", "record_text"]
