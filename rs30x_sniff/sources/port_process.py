"""A port read and stamped by a child process, so that decoding in this one never delays an arrival stamp."""

# A reply's latency is its first byte's time minus its request's end, both from when their bytes arrived
# (table 4.6 No. 7: a servo answers 100 us + 50 us x register 7 after a request). A reader thread shares the
# interpreter with the decoder: when its read returns while the decoder holds the lock, it waits for it (up
# to the 5 ms switch interval), and a request and its reply 2.7 ms apart were read as one piece about a third
# of the time, with no latency to give. Here the child does what SerialTap's thread did (read, drain a
# backlog, stamp) on a core of its own, and sends the stamped chunks in batches, SEND_SECONDS apart, through
# a pipe, which this side reads as it takes them (PipeQueue). The parent's Ctrl-C and SIGTERM are the parent's to
# act on: the child ignores them (systemd signals the whole group), and stops when its stdin closes, after
# reading what the OS still holds, as the thread did.

from __future__ import annotations

import os
import pickle
import queue
import select
import signal
import struct
import subprocess
import sys
import threading
import time
from array import array
from collections import deque
from itertools import accumulate
from typing import Any, BinaryIO, cast

from .captures import CaptureError
from .serial_tap import LOST, STOP_SIGNALS, Chunk, SerialTap, TapEnd, TapQueue

_PACKAGE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# The child sends what it stamped at most this often on a busy bus (one wake-up of the parent per batch,
# not per chunk); a chunk reaches the parent's queue within this, well inside the drive loop's gather time.
SEND_SECONDS = 0.01
OPEN_TIMEOUT = 30.0  # the child starts Python and opens the port: a loaded machine can take seconds
_HEAD = struct.Struct("<I")

# Messages, child -> parent (each its length, _HEAD, then its pickle):
#   ("open", wall_start_ns, start_ns)          the port is open
#   ("error", message)                         it could not be opened (a CaptureError's one line)
#   ("data", blob, lengths, times, stalls, n)  chunks: lengths array("I"), times array("d") as bytes; the
#                                              stalls found since the last message; bytes read so far
#   ("end", reason, message)                   the reader ended (a TapEnd)


class PortProcess:
    """The child reading ``tap``'s port: started (and the port open) when made; its chunks reach ``tap.queue`` (a
    :class:`PipeQueue`, read by whoever takes from it) and its stalls ``tap.stalls``; :meth:`stop` ends it."""

    def __init__(self, tap: SerialTap) -> None:
        import serial

        self.tap = tap
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, (_PACKAGE_ROOT, env.get("PYTHONPATH"))))
        proc = self._proc = subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE,
                                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
        to_child, from_child = proc.stdin, proc.stdout
        assert to_child is not None and from_child is not None  # both piped
        self._to_child, self._from_child = to_child, from_child
        args = {"port": tap.port, "baud": tap.baud, "read_timeout": tap.read_timeout,
                # URL handlers registered here (serial.protocol_handler_packages) are found there too
                "handlers": list(getattr(serial, "protocol_handler_packages", ())), "path": list(sys.path)}
        try:
            pickle.dump(args, to_child)
            to_child.flush()
        except OSError:
            pass  # the child is gone already: its first message says so
        self.queue = PipeQueue(from_child.fileno(), tap)
        msg = self.queue.first(OPEN_TIMEOUT)
        if msg[0] != "open":
            self._reap()
            raise CaptureError(msg[1] if msg[0] == "error" else f"{tap.port}: cannot open port: {msg[1]}")
        tap.wall_start_ns, tap.start_ns = msg[1], msg[2]
        tap.queue = self.queue

    @property
    def running(self) -> bool:
        return not self.queue.ended

    def stop(self, timeout: float) -> None:
        """Close the child's stdin (it reads what the OS holds, sends it and ends), and take its last chunks."""
        try:
            self._to_child.close()
        except OSError:
            pass
        self.queue.finish(timeout)
        self._reap(timeout)

    def _reap(self, timeout: float = 2.0) -> None:
        proc = self._proc
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        for f in (self._to_child, self._from_child):
            try:
                f.close()
            except OSError:
                pass


class PipeQueue:
    """The tap's queue (ChunkQueue's ``put``, ``get``, ``get_nowait``, ``empty``, ``take_all``) for a child's
    pipe, read in the thread that takes from it: no thread of its own here to wake per message and contend for
    the interpreter lock with the decoding (bench/live.py). The child keeps reading and stamping while this
    side decodes: a full pipe holds up only its sender thread."""

    def __init__(self, fd: int, tap: SerialTap) -> None:
        self._fd = fd
        self._tap = tap
        self._items: deque[Chunk | TapEnd] = deque()
        self._buf = bytearray()
        self._eof = False
        self.ended = False  # the child's end (or EOF) is read: nothing more comes

    def put(self, item: Chunk | TapEnd) -> None:
        self._items.append(item)

    def first(self, timeout: float) -> tuple:
        """The child's first message (its port open, or why not), waiting up to ``timeout``."""
        end = time.monotonic() + timeout
        while True:
            msg = self._message()
            if msg is not None:
                return msg
            if self._eof:
                return ("failed", "its reader process ended before opening the port")
            left = end - time.monotonic()
            if left <= 0:
                return ("failed", f"its reader process did not answer in {timeout:g} s")
            self._fill(left)

    def _fill(self, timeout: float) -> None:
        """Read what the pipe holds, waiting up to ``timeout`` for something (a signal's handler runs meanwhile)."""
        if self.ended or self._eof:
            return
        try:
            if not select.select((self._fd,), (), (), max(0.0, timeout))[0]:
                return
        except (OSError, ValueError):  # the pipe closed already (a source finalized late): nothing more comes
            self._eof = True
            return
        try:
            data = os.read(self._fd, 1 << 20)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if data:
            self._buf += data
        else:
            self._eof = True  # the child is gone: the whole messages before are still taken

    def _message(self) -> tuple | None:
        """The next whole message in the buffer, or None."""
        buf = self._buf
        if len(buf) < _HEAD.size:
            return None
        (n,) = _HEAD.unpack_from(buf)
        if len(buf) < _HEAD.size + n:
            return None
        msg = pickle.loads(buf[_HEAD.size:_HEAD.size + n])
        del buf[:_HEAD.size + n]
        return msg

    def _take(self, timeout: float) -> None:
        """Read the pipe (waiting up to ``timeout``) and queue the chunks of every whole message in it."""
        self._fill(timeout)
        tap, items = self._tap, self._items
        while not self.ended:
            msg = self._message()
            if msg is None:
                if self._eof:  # killed, out of memory: what came is kept
                    self._end(TapEnd(LOST, "its reader process ended"))
                return
            if msg[0] == "data":
                _, blob, lengths, times, stalls, n = msg
                sizes, ts = array("I"), array("d")
                sizes.frombytes(lengths)
                ts.frombytes(times)
                ends = list(accumulate(sizes))
                items.extend(zip([blob[a - k:a] for a, k in zip(ends, sizes)], ts))
                if stalls:
                    tap.stalls.extend(stalls)
                tap.bytes_read = n
            elif msg[0] == "end":
                self._end(TapEnd(msg[1], msg[2]))

    def _end(self, end: TapEnd) -> None:
        if not self.ended:
            self.ended = True
            self._items.append(end)

    def get(self, timeout: float | None = None) -> Chunk | TapEnd:
        items = self._items
        if not items:
            end = None if timeout is None else time.monotonic() + timeout
            while not items:
                left = 0.05 if end is None else end - time.monotonic()
                if left <= 0 or self.ended:
                    self._take(0)
                    if items:
                        break
                    raise queue.Empty
                self._take(left)
        return items.popleft()

    def get_nowait(self) -> Chunk | TapEnd:
        return self.get(0)

    def empty(self) -> bool:
        if not self._items:
            self._take(0)
        return not self._items

    def take_all(self) -> list[Chunk | TapEnd]:
        self._take(0)
        items = self._items
        return [items.popleft() for _ in range(len(items))]

    def finish(self, timeout: float) -> None:
        """After the child was asked to stop: queue what it still sends, up to its end (or ``timeout``)."""
        end = time.monotonic() + timeout
        while not self.ended:
            left = end - time.monotonic()
            if left <= 0:
                self._end(TapEnd(LOST, "its reader process did not stop"))
                return
            self._take(left)


class _Sender:
    """The child's stand-in for the tap's queue: what the reader stamps, sent in batches by a thread of its own."""

    def __init__(self, out: BinaryIO, tap: SerialTap) -> None:
        self.out = out
        self.tap = tap
        self.items: deque = deque()
        self.ready = threading.Event()
        self.thread = threading.Thread(target=self._send_all, name="send", daemon=True)
        self.thread.start()

    def put(self, item: object) -> None:
        self.items.append(item)
        if not self.ready.is_set():
            self.ready.set()

    def _send_all(self) -> None:
        items, ready = self.items, self.ready
        try:
            while True:
                ready.wait()
                if items and type(items[-1]) is not TapEnd:
                    time.sleep(SEND_SECONDS)  # a busy bus: let a batch gather
                ready.clear()  # before the batch is taken: a chunk put after it sets it again
                batch = [items.popleft() for _ in range(len(items))]
                end = batch.pop() if batch and type(batch[-1]) is TapEnd else None
                if batch:
                    self._send_chunks(batch)
                if end is not None:
                    self._dump(("end", end.reason, end.message))
                    return
        except OSError:
            self.tap.request_stop()  # the parent is gone: nobody to read for

    def _send_chunks(self, batch: list) -> None:
        # Sent stalls leave the child's list (the parent keeps them): it would grow for as long as the port is read.
        # A del of a slice and the reader's append hold the interpreter lock: none is lost between the two lines.
        pending = self.tap.stalls
        stalls = pending[:len(pending)]
        del pending[:len(stalls)]
        self._dump(("data", b"".join(d for d, _ in batch), array("I", [len(d) for d, _ in batch]).tobytes(),
                    array("d", [t for _, t in batch]).tobytes(), stalls, self.tap.bytes_read))

    def _dump(self, msg: tuple) -> None:
        _send(self.out, msg)


def _send(out: BinaryIO, msg: tuple) -> None:
    """One message to the parent: its length, then its pickle (PipeQueue reads whole ones)."""
    body = pickle.dumps(msg, protocol=pickle.HIGHEST_PROTOCOL)
    out.write(_HEAD.pack(len(body)) + body)
    out.flush()


def serve(args: dict[str, Any], stdin: BinaryIO, out: BinaryIO) -> None:
    """The child: open the port, send its opening, read it until stdin closes, send the end."""
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)  # the parent stops us (its stdin), after its own Ctrl-C or SIGTERM
    for entry in args["path"]:
        if entry not in sys.path:
            sys.path.append(entry)
    import serial

    for package in args["handlers"]:
        if package not in serial.protocol_handler_packages:
            serial.protocol_handler_packages.append(package)
    tap = SerialTap(args["port"], args["baud"], read_timeout=args["read_timeout"], process=False)
    try:
        tap.open_port()
    except CaptureError as e:
        _send(out, ("error", str(e)))
        return
    _send(out, ("open", tap.wall_start_ns, tap.start_ns))
    sender = _Sender(out, tap)
    tap.queue = cast(TapQueue, sender)  # in the child only the reader's put is called

    def watch() -> None:
        try:
            stdin.read()  # until the parent closes it (or dies)
        finally:
            tap.request_stop()

    threading.Thread(target=watch, name="stdin", daemon=True).start()
    try:
        tap.run()
    finally:
        sender.thread.join(5.0)
        tap.stop()


def main() -> None:
    stdin = sys.stdin.buffer
    try:
        serve(pickle.load(stdin), stdin, sys.stdout.buffer)
    except (BrokenPipeError, KeyboardInterrupt, EOFError):
        pass  # the parent went away: nobody to tell


if __name__ == "__main__":
    main()
