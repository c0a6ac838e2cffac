"""The core stays sans-IO: importing and running it loads none of pyserial, mcap or textual."""

import subprocess
import sys

CORE = ["rs30x_sniff.wire", "rs30x_sniff.events", "rs30x_sniff.framing", "rs30x_sniff.memmap",
        "rs30x_sniff.bus", "rs30x_sniff.pipeline", "rs30x_sniff.render", "rs30x_sniff.lint",
        "rs30x_sniff.stats", "rs30x_sniff.sim.servo", "rs30x_sniff.sim.scenarios"]


def test_core_imports_no_io_library():
    code = (
        "import sys\n"
        + "".join(f"import {m}\n" for m in CORE)
        + "from rs30x_sniff.pipeline import Decoder\n"
        "from rs30x_sniff.lint import Linter\n"
        "d = Decoder(None, Linter())\n"
        "d.feed(bytes.fromhex('FAAF01001E020184039B'), 0.0); d.close()\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('serial', 'mcap', 'textual'))\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == ""
