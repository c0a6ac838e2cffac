"""A capture file read by a child process with the same reader (read_input), so a second core parses it."""

# Reading a text capture is Python work that holds the GIL (a timestamped-hex line takes about 2.5 us:
# half of what the monitor spends on a million frames). A thread cannot overlap it with the decoding;
# a process can. The child sends the chunks in batches through a pipe as one bytes object, their
# lengths and their times (marked chunks, and untimed ones mixed with timed ones, as they are), with
# the reader's warnings and, at the end, its error, raised here as the same CaptureError.

from __future__ import annotations

import functools
import itertools
import os
import pickle
import subprocess
import sys
from array import array
from typing import Any, BinaryIO, cast
from collections.abc import Callable, Generator, Iterator

from ..protocol.chunks import Chunk
from .captures import CaptureError

_PACKAGE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BATCH_BYTES = 1 << 18  # chunk bytes per message: a few thousand chunks, a few milliseconds of decoding

# Messages, child -> parent (each one pickle):
#   ("data", blob, lengths, times)  plain chunks: lengths an array("I") as bytes, times an array("d") as
#                                   bytes, or None when every chunk of the batch has no time
#   ("chunks", [chunk, ...])        chunks as they are (marked ones, or times and None mixed)
#   ("warn", [message, ...])        what the reader worked around
#   ("error", message, line, column) a CaptureError
#   ("end",)


class ReadAhead:
    """The chunks ``read_input(path, fmt, ...)`` gives, read by a child process started at once (it reads
    while the caller gets ready); :meth:`close` (also at the end, or on an error) stops it."""

    def __init__(self, path: str, fmt: str | None = None, *, baud: int, time_ref: str | None = None,
                 warn: Callable[[str], None] | None = None, options: dict | None = None) -> None:
        self.path = path
        self.warn = warn
        # The child imports this very package, wherever it was imported from here.
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, (_PACKAGE_ROOT, env.get("PYTHONPATH"))))
        proc = self._proc = subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE,
                                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
        to_child, from_child = proc.stdin, proc.stdout
        assert to_child is not None and from_child is not None  # both piped
        self._from_child = from_child
        try:
            pickle.dump({"path": path, "fmt": fmt, "baud": baud, "time_ref": time_ref, "options": options},
                        to_child)
            to_child.close()
        except OSError:
            pass  # the child is gone already: reading says so
        self._chunks = self._receive()

    def __iter__(self) -> Iterator[Chunk]:
        return self._chunks

    def __next__(self) -> Chunk:
        return next(self._chunks)

    def close(self) -> None:
        self._chunks.close()
        proc = self._proc
        self._from_child.close()
        if proc.poll() is None:
            proc.kill()
        proc.wait()

    def _receive(self) -> Generator[Chunk, None, None]:
        try:
            # One pickle.load per message: an Unpickler kept across messages would keep every one (its memo).
            yield from receive(functools.partial(pickle.load, self._from_child), self.path, self.warn)
        finally:
            if self._proc.poll() is None:
                self._proc.kill()
            self._proc.wait()  # reaped: no zombie, whether it ended, failed or was stopped


def receive(load: Callable[[], Any], path: str, warn: Callable[[str], None] | None) -> Iterator[Chunk]:
    """The chunks in the messages ``load`` gives (the child's, as :func:`send_all` makes them)."""
    while True:
        try:
            msg = load()
        except (EOFError, pickle.UnpicklingError, OSError):
            raise CaptureError(f"{path}: the process reading it ended early") from None
        kind = msg[0]
        if kind == "data":
            _, blob, lengths, times = msg
            sizes = array("I")
            sizes.frombytes(lengths)
            ends = list(itertools.accumulate(sizes))
            datas = map(blob.__getitem__, map(slice, itertools.chain((0,), ends), ends))
            if times is None:
                yield from zip(datas, itertools.repeat(None))
            else:
                ts = array("d")
                ts.frombytes(times)
                yield from zip(datas, ts.tolist())
        elif kind == "chunks":
            yield from msg[1]
        elif kind == "warn":
            if warn is not None:
                for text in msg[1]:
                    warn(text)
        elif kind == "error":
            raise CaptureError(msg[1], line=msg[2], column=msg[3])
        else:
            return


def send_all(out: BinaryIO, args: dict[str, Any]) -> None:
    """The child: read the capture and send it, as the module comment says."""
    from .inputs import read_input

    def dump(msg: tuple) -> None:
        pickle.dump(msg, out, protocol=pickle.HIGHEST_PROTOCOL)  # a fresh memo each: nothing kept

    warnings: list[str] = []

    def send(msg: tuple) -> None:
        if warnings:
            dump(("warn", warnings[:]))
            warnings.clear()
        dump(msg)

    datas: list[bytes] = []
    times: list[float | None] = []
    size = 0

    def flush() -> None:
        nonlocal size
        if not datas:
            return
        if all(t is None for t in times):
            send(("data", b"".join(datas), array("I", map(len, datas)).tobytes(), None))
        elif None in times:
            send(("chunks", list(zip(datas, times))))
        else:  # no None among the times (checked above)
            stamps = array("d", cast("list[float]", times)).tobytes()
            send(("data", b"".join(datas), array("I", map(len, datas)).tobytes(), stamps))
        datas.clear()
        times.clear()
        size = 0

    try:
        for chunk in read_input(args["path"], args["fmt"], baud=args["baud"], time_ref=args["time_ref"],
                                warn=warnings.append, options=args["options"]):
            if type(chunk) is not tuple:  # Marked: its marks go as they are
                flush()
                send(("chunks", [chunk]))
                continue
            data, t = chunk
            datas.append(data)
            times.append(t)
            size += len(data)
            if size >= BATCH_BYTES:
                flush()
        flush()
        send(("end",))
    except CaptureError as e:
        flush()
        send(("error", str(e), e.line, e.column))
    except OSError as e:
        flush()
        send(("error", f"{args['path']}: cannot read: {e.strerror or e}", None, None))
    except Exception as e:  # noqa: BLE001 - a bug in a reader: the parent shows it in one line
        flush()
        send(("error", f"{args['path']}: reading failed: {type(e).__name__}: {e}", None, None))
    out.flush()


def main() -> None:
    try:
        send_all(sys.stdout.buffer, pickle.load(sys.stdin.buffer))
    except (BrokenPipeError, KeyboardInterrupt):
        pass  # the parent stopped reading: nothing to tell it


if __name__ == "__main__":
    main()
