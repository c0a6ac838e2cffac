"""A pyserial URL handler (``busywire://``) modelling a never-idle wire: simulator traffic paced at the line rate,
always a byte waiting, and each call taking time, as a loaded reader or a slow driver does.

Registered by ``serial.protocol_handler_packages.append("tests.sources")``. Options in the URL's query:
``baud`` (the wire's rate, default 115200; a port opened at another rate reads noise, as a UART would),
``delay`` (seconds each read and in_waiting call takes, default 0.0003: over three byte times at 115200),
``scenario`` (the simulator's, default hexapod, replayed in a loop).
"""

from __future__ import annotations

import time
import urllib.parse

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from rs30x_sniff.protocol.wire import byte_time
from rs30x_sniff.sim import run


class Serial(SerialBase):
    def open(self) -> None:
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        query = urllib.parse.parse_qs(urllib.parse.urlsplit(self._port).query)
        self.wire_baud = int(query.get("baud", ["115200"])[0])
        self.delay = float(query.get("delay", ["0.0003"])[0])
        scenario = query.get("scenario", ["hexapod"])[0]
        self.stream = b"".join(d for d, _ in run(scenario, baud=self.wire_baud, duration=2.0))
        self.bt = byte_time(self.wire_baud)
        self.opened = time.monotonic()
        self.taken = 0
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def _reconfigure_port(self) -> None:
        pass

    def _due(self) -> int:
        """Bytes on the wire so far, less those read: the line never goes quiet."""
        return int((time.monotonic() - self.opened) / self.bt) - self.taken

    @property
    def in_waiting(self) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        time.sleep(self.delay)
        return max(0, self._due())

    def read(self, size: int = 1) -> bytes:
        if not self.is_open:
            raise PortNotOpenError()
        time.sleep(self.delay)
        while self._due() < size:  # a byte at a time comes at the line rate
            time.sleep(self.bt)
        start = self.taken % len(self.stream)
        out = (self.stream[start:] + self.stream)[:size]
        self.taken += size
        if self._baudrate != self.wire_baud:  # read at a wrong rate: noise, no frame
            out = bytes((b * 37 + 11) & 0xF7 for b in out)
        return out

    def reset_input_buffer(self) -> None:
        self.taken += max(0, self._due())

    def write(self, data: bytes) -> int:
        raise SerialException("busywire: a tap never writes")
