"""The numpy framing kernel: where a clean run of back-to-back intact frames starts and ends, in one pass."""

from __future__ import annotations

import numpy as np

from ..protocol.wire import (
    AT_COUNT, AT_ID, AT_LENGTH, FRAME_OVERHEAD, HEADER_SIZE, REQUEST_HEADER, RETURN_HEADER, SUM_SIZE)

_REQ0, _REQ1 = REQUEST_HEADER  # FA AF: short and long packets
_RET0, _RET1 = RETURN_HEADER   # FD DF: return packets
# Header layout shared by every packet (chapter 4, "Format of Packets", protocol.wire): two sync bytes, ID,
# Flag, Address, Length, Count, then the data and one Sum byte, the XOR of ID through the last data byte.
_NONE = np.zeros(0, dtype=np.intp)


def scan_regular_arrays(window: bytes, max_data: int) -> tuple[np.ndarray, np.ndarray, bool]:
    """The intact frames that tile ``window`` back to back from its first byte: (starts, ends, more).

    A frame counts when it is what the frame decoder would take at a clean boundary without a second
    look: FA AF or FD DF, all its bytes in the window, data length (Length x Count for a request,
    Length for a return) at most ``max_data``, and a Sum equal to the XOR of ID through data. The run
    stops at the first place where no such frame starts exactly where the last one ended: ``more`` is
    True when that is only because the window ends inside a frame that may be whole in a longer one,
    False at an irregularity (noise, a corrupt or oversized frame, an ACK byte), where the caller's
    state machine takes over. Every candidate header is checked at once with numpy; only the chain's
    end is looked for.
    """
    a = np.frombuffer(window, dtype=np.uint8)
    n = a.size
    if n < HEADER_SIZE:
        return _NONE, _NONE, True
    head, nxt = a[:n - HEADER_SIZE + 1], a[1:n - HEADER_SIZE + 2]  # every start with a whole header
    sync = ((head == _REQ0) & (nxt == _REQ1)) | ((head == _RET0) & (nxt == _RET1))
    cand = np.flatnonzero(sync)
    if cand.size == 0 or cand[0] != 0:
        return _NONE, _NONE, False
    length = a[cand + AT_LENGTH].astype(np.int64)
    data_len = np.where(a[cand] == _REQ0, length * a[cand + AT_COUNT], length)
    ends = cand + FRAME_OVERHEAD + data_len
    whole = (data_len <= max_data) & (ends <= n)
    last = np.minimum(ends, n) - SUM_SIZE   # the Sum byte (clipped for frames not all here: masked by ``whole``)
    running = np.bitwise_xor.accumulate(a)   # running[k] = a[0] ^ ... ^ a[k]
    # XOR of ID..data = running[last - 1] ^ running[start + AT_ID - 1] (the two sync bytes drop out).
    ok = whole & ((running[last - 1] ^ running[cand + (AT_ID - 1)]) == a[last])
    starts, stops = cand[ok], ends[ok]
    if starts.size and starts[0] == 0:
        broken = np.flatnonzero(stops[:-1] != starts[1:])
        k = int(broken[0]) + 1 if broken.size else starts.size
        starts, stops = starts[:k], stops[:k]
        stop = int(stops[-1])
    else:
        starts, stops, stop = starts[:0], stops[:0], 0
    # Why the run ended: the window ran out (too few bytes for a header, or a plausible frame whose
    # end lies beyond the window), or an irregularity the state machine must look at.
    if stop + HEADER_SIZE > n:
        more = True
    else:
        at = np.searchsorted(cand, stop)
        more = bool(at < cand.size and cand[at] == stop and data_len[at] <= max_data and ends[at] > n)
    return starts, stops, more
