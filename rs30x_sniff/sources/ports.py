"""Whether an INPUT names a serial port or a capture file: asked by every command, before any port is opened."""

# Apart from serial_tap (the reader itself, and pyserial behind it): a command given a capture file pays for
# neither at start-up.

from __future__ import annotations

import os
import stat


def is_port(path: str) -> bool:
    """Whether INPUT names a serial port: a pyserial URL (rfc2217://, socket://, loop://, ...) or a
    character device other than the memory devices (/dev/null, /dev/zero, ...)."""
    if "://" in path:
        return True
    try:
        st = os.stat(path)
    except OSError:
        return False
    # Major 1 on Linux holds /dev/null, /dev/zero, /dev/random...: files, not ports.
    return stat.S_ISCHR(st.st_mode) and os.major(st.st_rdev) != 1
