"""PulseView and Wireshark run under Xvfb on a capture with faults, and their windows as PNG screenshots.

`python -m tests.plugins.screens OUTDIR` writes pulseview.png and wireshark.png (docs/integrations.md shows
them); tests/plugins/test_screens.py looks at the pixels. Needs Debian's xvfb, pulseview, wireshark-qt and
imagemagick (`import`), sigrok-cli and numpy (the .sr file).
"""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rs30x_sniff.cli import main
from rs30x_sniff.plugins import sigrok, wireshark
from rs30x_sniff.plugins.maps import plugin_maps
from rs30x_sniff.protocol import wire
from tests.plugins.sigrok_fixtures import BAUD, write_sr

PROGRAMS = ("Xvfb", "pulseview", "wireshark", "import", "sigrok-cli")
SCREEN = (1600, 900)
SETTLE_S = 2.0    # a window that has not changed for this long is drawn
PATIENCE_S = 90.0  # at most this long for a program's window to settle


def missing_programs() -> list[str]:
    return [p for p in PROGRAMS if shutil.which(p) is None]


def with_sum(frame: bytes) -> bytes:
    """``frame`` (its Sum left off) with the XOR Sum over ID..data ("Format of Packets")."""
    x = 0
    for b in frame[2:]:
        x ^= b
    return frame + bytes((x,))


def fault_chunks() -> list[tuple[bytes, float]]:
    """A read answered, one with a bad Sum, one with none (NO-REPLY), a temperature alarm, noise, a model
    number: every fault of issue 34 §6 in 11 ms of bus."""
    read = wire.encode_read(1, 42, 12)
    values = bytes.fromhex("8403 0000 0000 0000 2d00 e402")
    ret = wire.encode_return(1, 42, values)
    bad = ret[:-1] + bytes((ret[-1] ^ 0x55,))
    alarm = with_sum(ret[:3] + bytes((0x20,)) + ret[4:-1])  # flags bit 5: temperature alarm (table 4.4)
    return [(read, 0.0), (bad, 0.0008), (wire.encode_read(2, 42, 2), 0.0027), (read, 0.0037), (alarm, 0.0045),
            (b"\x55\x13", 0.0066), (wire.encode_read(3, 0, 2), 0.0070),
            (wire.encode_return(3, 0, (0x3030).to_bytes(2, "little")), 0.0078), (read, 0.0090), (ret, 0.0098)]


def gvariant_int64(value: int) -> str:
    """A QSettings byte array holding a serialized GVariant int64 (how PulseView keeps a decoder option)."""
    return "@ByteArray(" + "".join(f"\\x{b:x}" for b in struct.pack("<q", value)) + ")"


def pulseview_session(sr: Path, seconds_per_pixel: float) -> Path:
    """The session setup PulseView reads beside ``sr`` (``NAME.pvs``): uart on D0 at the bus's rate, rs30x
    stacked on it, the view's zoom. PulseView writes this QSettings file with "Save session setup"."""
    pvs = sr.with_suffix(".pvs")
    pvs.write_text(f"""[General]
decode_signals=1
generated_signals=0
views=1
meta_objs=0

[decode_signal0]
name=RS30x
enabled=true
decoders=2
decoder0\\id=uart
decoder0\\visible=true
decoder0\\options=1
decoder0\\option0\\name=baudrate
decoder0\\option0\\type=x
decoder0\\option0\\value={gvariant_int64(BAUD)}
decoder1\\id=rs30x
decoder1\\visible=true
decoder1\\options=0
channels=1
channel0\\name=RX
channel0\\initial_pin_state=2
channel0\\assigned_signal_name=D0

[view0]
scale={seconds_per_pixel!r}
v_offset=0
""")
    return pvs


def write_files(folder: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_text(text, encoding="utf-8")


def screenshot(cmd: list[str], env: dict[str, str], png: Path, cwd: Path, crop: str) -> Path:
    """Run ``cmd`` on an Xvfb display of its own until its screen stops changing, and save the part ``crop``
    (ImageMagick's geometry, WxH+X+Y) of the screen as ``png``."""
    read_fd, write_fd = os.pipe()
    xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(write_fd), "-screen", "0", f"{SCREEN[0]}x{SCREEN[1]}x24",
                             "-nolisten", "tcp"], pass_fds=(write_fd,), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    os.close(write_fd)
    app = None
    try:
        with os.fdopen(read_fd) as f:
            display = ":" + f.readline().strip()
        run_env = {**env, "DISPLAY": display}
        app = subprocess.Popen(cmd, env=run_env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        last, same_since, deadline = b"", None, time.monotonic() + PATIENCE_S
        while time.monotonic() < deadline:
            time.sleep(0.5)
            shot = subprocess.run(["import", "-window", "root", "ppm:-"], env=run_env, capture_output=True).stdout
            now = time.monotonic()
            if shot and shot == last:
                if same_since is not None and now - same_since >= SETTLE_S:
                    break
                same_since = same_since or now
            else:
                last, same_since = shot, None
        subprocess.run(["import", "-window", "root", "-crop", crop, "+repage", f"png:{png}"], env=run_env,
                       check=True, capture_output=True)
        return png
    finally:
        for p in (app, xvfb):
            if p is not None:
                p.terminate()
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()


# PulseView at two zooms: a packet's fields (5.5 us a pixel) and the whole capture (12 us a pixel).
ZOOMS = {"pulseview": 5.5e-6, "pulseview-overview": 1.2e-5}
PULSEVIEW_CROP = "1000x215+0+95"   # its rulers and rows (the window is 1000 x 720 at the top left)
WIRESHARK_CROP = f"{SCREEN[0]}x290+0+0"  # its packet list


def take(out: Path) -> dict[str, Path]:
    """The screenshots in ``out``: PulseView on a .sr of fault_chunks() at each of ZOOMS, Wireshark (with the
    profile the plug-in ships) on its pcapng. Only the bundled maps are used, as the tests' plug-ins are."""
    out.mkdir(parents=True, exist_ok=True)
    saved = os.environ.pop("RS30X_DECODERS", None)
    try:
        maps = plugin_maps()
    finally:
        if saved is not None:
            os.environ["RS30X_DECODERS"] = saved
    with tempfile.TemporaryDirectory(prefix="rs30x-screens-") as tmp_name:
        tmp = Path(tmp_name)
        home = tmp / "home"
        env = {k: v for k, v in os.environ.items() if not k.startswith(("WIRESHARK_", "XDG_"))}
        env.update(HOME=str(home), XDG_CONFIG_HOME=str(home / ".config"), XDG_RUNTIME_DIR=str(tmp),
                   QT_QPA_PLATFORM="xcb", SIGROKDECODE_DIR=str(tmp / "decoders"))
        write_files(tmp / "decoders", sigrok.generate(maps))
        write_files(tmp / "wireshark", wireshark.generate(maps))
        sr = write_sr(tmp / "faults.sr", fault_chunks(), trail=0.02)
        shots = {}
        for name, zoom in ZOOMS.items():
            pulseview_session(sr, zoom)
            shots[name] = screenshot(["pulseview", "-c", "-i", sr.name], env, out / f"{name}.png", tmp,
                                     PULSEVIEW_CROP)
        pcapng = tmp / "faults.pcapng"
        assert main(["convert", str(sr), "--channel", "D0", "--baud", str(BAUD), "-o", str(pcapng),
                     "--isolated"]) == 0
        config = home / ".config" / "wireshark"
        shutil.copytree(tmp / "wireshark" / wireshark.PROFILE_DIR, config / "profiles" / wireshark.PROFILE)
        (config / "recent_common").write_text("gui.geometry_main_x: 0\ngui.geometry_main_y: 0\n"
                                              f"gui.geometry_main_width: {SCREEN[0]}\n"
                                              f"gui.geometry_main_height: {SCREEN[1] // 2}\n")
        shots["wireshark"] = screenshot(["wireshark", "-C", wireshark.PROFILE, "-X",
                                         f"lua_script:{tmp / 'wireshark' / wireshark.LUA_FILE}", "-r", str(pcapng)],
                                        env, out / "wireshark.png", tmp, WIRESHARK_CROP)
    return shots


if __name__ == "__main__":
    if missing_programs():
        sys.exit(f"screens: needs {', '.join(missing_programs())} (apt-get install xvfb pulseview wireshark-qt "
                 "imagemagick sigrok-cli)")
    for name, path in take(Path(sys.argv[1] if len(sys.argv) > 1 else ".")).items():
        print(f"{name}: {path}")
