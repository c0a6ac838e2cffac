"""The core stays sans-IO: importing and running it loads none of pyserial, mcap or textual."""

import subprocess
import sys

CORE = ["rs30x_sniff.protocol.wire", "rs30x_sniff.protocol.events", "rs30x_sniff.decode.framing", "rs30x_sniff.protocol.memmap",
        "rs30x_sniff.decode.pairing", "rs30x_sniff.decode.decoder", "rs30x_sniff.sinks.pipeline", "rs30x_sniff.render.records", "rs30x_sniff.lint",
        "rs30x_sniff.sinks.stats", "rs30x_sniff.sim.servo", "rs30x_sniff.sim.scenarios"]


def test_core_imports_no_io_library():
    code = (
        "import sys\n"
        + "".join(f"import {m}\n" for m in CORE)
        + "from rs30x_sniff.decode.decoder import Decoder\n"
        "from rs30x_sniff.lint import Linter\n"
        "d = Decoder(None, Linter())\n"
        "d.feed(bytes.fromhex('FAAF01001E020184039B'), 0.0); d.close()\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('serial', 'mcap', 'textual'))\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == ""
