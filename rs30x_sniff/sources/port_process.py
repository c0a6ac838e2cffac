"""A port read and stamped by a child process, so that decoding in this one never delays an arrival stamp."""

# A reply's latency is its first byte's time minus its request's end, both from when their bytes arrived
# (table 4.6 No. 7: a servo answers 100 us + 50 us x register 7 after a request). A reader thread shares the
# interpreter with the decoder: when its read returns while the decoder holds the lock, it waits for it (up
# to the 5 ms switch interval), and a request and its reply 2.7 ms apart were read as one piece about a third
# of the time, with no latency to give. Here the child does what SerialTap's thread did (read, drain a
# backlog, stamp) on a core of its own, and sends the stamped chunks in batches, SEND_SECONDS apart, through
# a pipe; a thread here puts them in the tap's queue. The parent's Ctrl-C and SIGTERM are the parent's to
# act on: the child ignores them (systemd signals the whole group), and stops when its stdin closes, after
# reading what the OS still holds, as the thread did.

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import threading
import time
from array import array
from collections import deque
from typing import Any, BinaryIO

from .captures import CaptureError
from .serial_tap import LOST, STOP_SIGNALS, SerialTap, TapEnd

_PACKAGE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# The child sends what it stamped at most this often on a busy bus (one wake-up of the parent per batch,
# not per chunk); a chunk reaches the parent's queue within this, well inside the drive loop's gather time.
SEND_SECONDS = 0.01
OPEN_TIMEOUT = 30.0  # the child starts Python and opens the port: a loaded machine can take seconds

# Messages, child -> parent (each one pickle):
#   ("open", wall_start_ns, start_ns)          the port is open
#   ("error", message)                         it could not be opened (a CaptureError's one line)
#   ("data", blob, lengths, times, stalls, n)  chunks: lengths array("I"), times array("d") as bytes; the
#                                              stalls found since the last message; bytes read so far
#   ("end", reason, message)                   the reader ended (a TapEnd)


class PortProcess:
    """The child reading ``tap``'s port: started (and the port open) when made, its chunks going to
    ``tap.queue`` and its stalls to ``tap.stalls``; :meth:`stop` ends it."""

    def __init__(self, tap: SerialTap) -> None:
        import serial

        self.tap = tap
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, (_PACKAGE_ROOT, env.get("PYTHONPATH"))))
        self._proc = subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE,
                                      stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
        args = {"port": tap.port, "baud": tap.baud, "read_timeout": tap.read_timeout,
                # URL handlers registered here (serial.protocol_handler_packages) are found there too
                "handlers": list(getattr(serial, "protocol_handler_packages", ())), "path": list(sys.path)}
        try:
            pickle.dump(args, self._proc.stdin)
            self._proc.stdin.flush()
        except OSError:
            pass  # the child is gone already: its first message says so
        msg = self._first()
        if msg[0] != "open":
            self._reap()
            raise CaptureError(msg[1] if msg[0] == "error" else f"{tap.port}: cannot open port: {msg[1]}")
        tap.wall_start_ns, tap.start_ns = msg[1], msg[2]
        self._thread = threading.Thread(target=self._receive, name=f"tap {tap.port}", daemon=True)
        self._thread.start()

    def _first(self) -> tuple:
        result: list[tuple] = []

        def load() -> None:
            try:
                result.append(pickle.load(self._proc.stdout))
            except Exception as e:  # noqa: BLE001 - EOF, a broken pipe: the child ended before opening
                result.append(("failed", f"its reader process ended ({type(e).__name__})"))

        waiter = threading.Thread(target=load, daemon=True)
        waiter.start()
        waiter.join(OPEN_TIMEOUT)
        return result[0] if result else ("failed", f"its reader process did not answer in {OPEN_TIMEOUT:g} s")

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _receive(self) -> None:
        tap, put = self.tap, self.tap.queue.put
        if hasattr(signal, "pthread_sigmask"):
            # Ctrl-C and SIGTERM go to the main thread, whose handler stops the capture (see SerialTap.run).
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        load = self._proc.stdout
        end = TapEnd(LOST, "its reader process ended")
        try:
            while True:
                msg = pickle.load(load)  # one load per message: an Unpickler kept across them keeps them all
                if msg[0] == "data":
                    _, blob, lengths, times, stalls, n = msg
                    sizes, ts = array("I"), array("d")
                    sizes.frombytes(lengths)
                    ts.frombytes(times)
                    at = 0
                    for size, t in zip(sizes, ts):
                        put((blob[at:at + size], t))
                        at += size
                    if stalls:
                        tap.stalls.extend(stalls)
                    tap.bytes_read = n
                elif msg[0] == "end":
                    end = TapEnd(msg[1], msg[2])
                    break
        except Exception:  # noqa: BLE001 - EOF or a broken pipe: the child died (killed, out of memory)
            pass
        put(end)

    def stop(self, timeout: float) -> None:
        """Close the child's stdin (it reads what the OS holds, sends it and ends), wait for its last chunks."""
        try:
            self._proc.stdin.close()
        except OSError:
            pass
        self._thread.join(timeout)
        self._reap(timeout)

    def _reap(self, timeout: float = 2.0) -> None:
        proc = self._proc
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        for f in (proc.stdin, proc.stdout):
            try:
                f.close()
            except OSError:
                pass


class _Sender:
    """The child's stand-in for the tap's queue: what the reader stamps, sent in batches by a thread of its own."""

    def __init__(self, out: BinaryIO, tap: SerialTap) -> None:
        self.out = out
        self.tap = tap
        self.items: deque = deque()
        self.ready = threading.Event()
        self.sent_stalls = 0
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
        stalls = self.tap.stalls[self.sent_stalls:]
        self.sent_stalls += len(stalls)
        self._dump(("data", b"".join(d for d, _ in batch), array("I", [len(d) for d, _ in batch]).tobytes(),
                    array("d", [t for _, t in batch]).tobytes(), stalls, self.tap.bytes_read))

    def _dump(self, msg: tuple) -> None:
        pickle.dump(msg, self.out, protocol=pickle.HIGHEST_PROTOCOL)
        self.out.flush()


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
        pickle.dump(("error", str(e)), out)
        out.flush()
        return
    pickle.dump(("open", tap.wall_start_ns, tap.start_ns), out)
    out.flush()
    sender = _Sender(out, tap)
    tap.queue = sender

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
