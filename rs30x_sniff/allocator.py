"""glibc's malloc told once at start-up to keep large buffers between blocks, not give them back and take them again."""

from __future__ import annotations

import ctypes
import sys

# mallopt's options (glibc's <malloc.h>).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
# A block's numpy buffers are a few MB each: glibc's default (128 KiB, raised by each freed mapping up to 32 MiB)
# maps each one afresh and unmaps it when freed, and trims the heap's top above 128 KiB, so every block pays for its
# pages again: 100k page faults and 0.2 s of system time for a 300k-frame lint (issue 35). Buffers up to 32 MiB
# (glibc's largest threshold on 64 bits) come from the heap, and up to 64 MiB of it freed stays for the next block.
# Setting either also stops glibc's sliding threshold, so the figures hold from the first block.
SETTINGS = ((M_MMAP_THRESHOLD, 32 << 20), (M_TRIM_THRESHOLD, 64 << 20))

_state = {"done": False}


def glibc() -> ctypes.CDLL | None:
    """The C library of this process if it is glibc (it has mallopt and these options); None elsewhere."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None)
    except OSError:
        return None
    # musl and others may name a mallopt that ignores these options: glibc alone says its version.
    if not hasattr(libc, "gnu_get_libc_version") or not hasattr(libc, "mallopt"):
        return None
    return libc


def keep_large_buffers(libc: ctypes.CDLL | None = None) -> bool:
    """Set SETTINGS with mallopt, once per process (a later call does nothing); ``libc``: the C library to tell,
    glibc's by default. Returns whether it set them: False off glibc, or when mallopt refused, or if done before."""
    if _state["done"]:
        return False
    _state["done"] = True
    libc = libc if libc is not None else glibc()
    if libc is None:
        return False
    mallopt = libc.mallopt
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return all([mallopt(option, value) == 1 for option, value in SETTINGS])  # 1: accepted, 0: refused
