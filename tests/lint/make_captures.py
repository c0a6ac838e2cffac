"""Writes captures/lint/<CODE>-<name>.hex|.thex: one small capture per rule, expectations beside the packets.

Run from the repository root: python tests/lint/make_captures.py (the files are committed; this is how they
were made). Each line is one frame; `# expect: CODE` names the findings that frame must get, and the test
fails on any finding not written down. Healthy frames around the faulty ones guard against false alarms.
"""

from __future__ import annotations

from pathlib import Path

from rs30x_sniff.lint import RULES
from rs30x_sniff.lint.registry import frame
from rs30x_sniff.protocol.wire import encode_command, encode_long, encode_read, encode_return, encode_short
from rs30x_sniff.sim.wire import retime

OUT = Path(__file__).resolve().parents[2] / "captures" / "lint"
RET = b"\xfd\xdf"


def w(sid, address, data, flag=0):
    return encode_short(sid, flag, address, data)


def goal(sid, deg10, gt=None):
    d = deg10.to_bytes(2, "little", signed=True) + (b"" if gt is None else gt.to_bytes(2, "little"))
    return w(sid, 0x1E, d)


def ret(sid, address, data, flags=0):
    return encode_return(sid, address, data, flags)


POS = bytes.fromhex("8403")                # 90.0 deg
READ1, RET1 = encode_read(1, 0x2A, 2), ret(1, 0x2A, POS)
POLL = encode_short(1, 0x09, 0, b"", length=0, count=1)
POLL2 = encode_short(2, 0x09, 0, b"", length=0, count=1)


def read_model(sid):
    return encode_read(sid, 0, 2)  # model number, addresses 0-1 (table 4.5)

STATUS = bytes(18)

# 18 goal writes sent back to back at 115200 bit/s, as a sniffer left at 57600 reads them (F007).
WRONG_BAUD = b"".join(d for d, _ in retime(
    [(b"".join(goal(sid, 900 - 50 * sid) for sid in range(1, 19)), 0.0)], 115200, 57600))

# code -> (comment, [(frame, expects, note) or (t, frame, expects, note)])
CASES: dict[str, tuple[str, list]] = {
    "F001": ("a corrupted write between two good ones", [
        (goal(1, 900), "", "goal 90.0 deg, intact"),
        (goal(1, 900)[:-1] + b"\x9c", "F001", "same packet, Sum wrong"),
        (READ1, "", "read present_position"), (RET1, "", "its return"),
        (RET1[:-1] + b"\x00", "F001", "a return with a bad Sum: the request above was answered"),
    ]),
    "F002": ("stray bytes between frames", [
        (goal(1, 900), "", ""), (bytes.fromhex("00 55 AA"), "F002", "noise"),
        (goal(2, 900), "", ""),
    ]),
    "F003": ("a frame cut short by its sender", [
        (0.000, goal(1, 900), "", ""), (0.010, goal(2, 900)[:7], "F003", "only 7 of 10 bytes, then silence"),
        (0.020, goal(3, 900), "", ""),
        (0.030, goal(4, 900)[:7], "", "cut by the end of the capture: no fault of the bus"),
    ]),
    "F004": ("bytes of one frame with idle time between them", [
        (0.000, goal(1, 900), "", "back to back: fine"),
        (0.010, goal(2, 900)[:4], "F004", "first 4 bytes ..."),
        (0.0111, goal(2, 900)[4:], "", "... the rest 0.75 ms later"),
        (0.020, goal(3, 900)[:4], "", "first 4 bytes ..."),
        (0.02037, goal(3, 900)[4:], "", "... the rest 0.02 ms late: within 5 byte times"),
    ]),
    "F005": ("a logger's timestamps that go back in time", [
        (0.100, READ1, "", "read present_position"),
        (0.095, RET1, "F005", "its return, stamped 5 ms before the read"),
        (0.200, goal(1, 900), "", ""),
        (0.196, goal(2, 900), "", "back again: counted, not flagged twice"),
    ]),
    "F010": ("two captures joined: the clock restarts at 0", [
        (0.000000, READ1, "", ""), (0.000800, RET1, "", ""),
        (3.000000, encode_read(2, 0x2A, 2), "", "the first capture's last request ..."),
        (0.000000, READ1, "F010", "... and the second capture's first: nothing is paired across the seam"),
        (0.000800, RET1, "", ""),
    ]),
    "F006": ("chunks stamped closer than their bytes could travel at 115200 bit/s", [
        (0.0000, goal(1, 900), "", "10 bytes take 0.868 ms"),
        (0.0005, goal(2, 900), "F006", "stamped 0.5 ms after the previous began"),
        (0.0100, goal(3, 900), "", "well after"),
    ]),
    "F007": ("the host moves the bus from 57600 to 115200 bit/s; the sniffer stays at 57600", [
        (goal(1, 900), "", "at 57600: fine"),
        (w(1, 0x06, b"\x07"), "", "baud_rate code 7: 115200 (table 4.7) ..."),
        (encode_command(1, 0x40), "", "... flashed ..."), (encode_command(1, 0x20), "", "... rebooted"),
        (WRONG_BAUD, "F002 F007", "18 goal writes at 115200 read at 57600: 73 bytes, no frame"),
    ]),
    "P001": ("flag bit 7", [(w(1, 0x1E, POS, 0x80), "P001", ""), (goal(1, 900), "", "")]),
    "P002": ("a long packet with a flag", [
        (frame(0, 0x40, 0x1E, 3, 2, 1, 0x64, 0, 2, 0x64, 0), "P002", "flash bit in a long packet"),
        (encode_long(0x1E, [(1, b"\x64\x00"), (2, b"\x64\x00")]), "", "the same, flag 0"),
    ]),
    "P003": ("long packets that write nothing", [
        (frame(0, 0, 0x1E, 1, 0), "P003", "Length 1, Count 0"),
        (frame(0, 0, 0x1E, 1, 2, 1, 2), "P003", "Length 1: VIDs only"),
        (encode_long(0x1E, [(1, b"\x64\x00")]), "", "one servo: fine"),
    ]),
    "P004": ("a VID twice in a long packet", [
        (encode_long(0x1E, [(1, b"\x64\x00"), (1, b"\xf4\x01")]), "P004", ""),
        (encode_long(0x1E, [(1, b"\x64\x00"), (2, b"\xf4\x01")]), "", ""),
    ]),
    "P005": ("IDs no servo can have", [
        (goal(200, 900), "P005", "ID 200"),
        (encode_long(0x1E, [(1, b"\x64\x00"), (128, b"\x64\x00")]), "P005", "VID 128"),
        (goal(127, 900), "", "ID 127: fine"), (goal(255, 900), "", "broadcast: fine"),
    ]),
    "P006": ("wrong Count", [
        (frame(1, 0, 0x1E, 1, 2, 0x84, 0x03), "P006", "Length 1, Count 2"),
        (frame(1, 0x0F, 0x2A, 2, 1, 0, 0), "P006 M001 B002", "a read with Count 1 (its bytes land on present_position)"),
        (READ1, "", ""), (RET1, "", ""), (POLL, "", "flag 09 poll, Length 0, Count 1: fine"),
        (ret(1, 42, STATUS), "", ""),
    ]),
    "P007": ("an undefined return mode", [(w(1, 0x1E, POS, 0x02), "P007", "mode 0010"), (goal(1, 900), "", "")]),
    "P008": ("command packets in the wrong form", [
        (frame(1, 0x40, 0x07, 1, 1, 0x12), "P008", "flash with data"),
        (frame(1, 0x20, 0x00, 0, 0), "P008", "reboot with Address 00"),
        (encode_command(1, 0x40), "", "flash: fine"),
        (frame(1, 0x10, 0xFF, 0xFF, 0), "", "initialize with Length FF: accepted"),
        (encode_command(1, 0x10), "", "initialize with Length 0: fine"),
    ]),
    "P009": ("flash and reboot in one packet", [
        (encode_command(1, 0x60), "P009", ""), (encode_command(1, 0x40), "", ""), (encode_command(1, 0x20), "", ""),
        (read_model(2), "", ""), (ret(2, 0, bytes.fromhex("1030")), "", "servo 2 is an RS301CR"),
        (encode_command(2, 0x60), "", "its manual allows the two in one packet (p.12)"),
    ]),
    "P010": ("broadcast asking for replies", [
        (encode_read(255, 0x2A, 2), "P010", "nobody answers here: B002 is not said for broadcasts"),
        (w(255, 0x24, b"\x01"), "", "broadcast torque on: fine"),
    ]),
    "P011": ("reads outside the map", [
        (encode_read(1, 0x80, 16), "P011 B002", "128-143"),
        (encode_read(1, 0x2A, 0), "P011 B002", "length 0"),
        (encode_read(1, 0x7C, 16), "", "124-139: fine"), (ret(1, 0x7C, bytes(16)), "", ""),
    ]),
    "P012": ("a return with Count 2", [
        (READ1, "", ""), (frame(1, 0, 0x2A, 2, 2, 0x84, 0x03, header=RET), "P012", ""),
    ]),
    "P013": ("a return with a reserved status bit", [
        (READ1, "", ""), (ret(1, 0x2A, POS, 0x40), "P013", ""), (READ1, "", ""), (RET1, "", ""),
    ]),
    "M001": ("writes to read-only registers", [
        (w(1, 0x2A, POS), "M001", "present_position"), (w(1, 0x00, b"\x30\x30"), "M001", "model_number"),
        (w(1, 0x0E, b"\x50\x00"), "M001", "temperature_limit"), (goal(1, 900), "", ""),
    ]),
    "M002": ("writes to reserved bytes", [
        (w(1, 0x10, bytes.fromhex("18FC")), "M002", "the manual's slip: 0x10 instead of 0x0A"),
        (w(1, 0x22, b"\x00"), "M002", "address 34 alone"),
        (w(1, 0x1E, bytes.fromhex("8403 0000 00 64")), "", "30-35 across reserved 34: carried along, fine"),
    ]),
    "M003": ("values outside the settable range", [
        (w(1, 0x23, bytes((120,))), "M003", "max_torque 120"),
        (w(1, 0x06, bytes((12,))), "M003 Q001", "baud_rate code 12 (and never flashed)"),
        (goal(1, 1600), "M003", "160.0 deg"), (goal(2, 900, 20000), "M003", "goal_time 200 s"),
        (w(1, 0x04, bytes((0,))), "M003 Q002", "servo_id 0"),
        (w(1, 0x23, bytes((100,))), "", "max_torque 100: fine"),
    ]),
    "M004": ("half of a 2-byte register", [
        (w(1, 0x1F, b"\x03"), "M004", "goal_position high byte"),
        (encode_long(0x1E, [(1, b"\x84"), (2, b"\x84")]), "M004", "low byte only, in a long packet"),
        (w(1, 0x1E, POS), "", ""),
    ]),
    "M005": ("model numbers no memory map knows", [
        (encode_read(1, 0x00, 2), "", "read model_number"), (ret(1, 0x00, b"\x0c\x30"), "M005", "0x300C"),
        (encode_read(1, 0x00, 2), "", ""), (ret(1, 0x00, b"\x0c\x30"), "", "said once per servo"),
        (encode_read(2, 0x00, 2), "", ""), (ret(2, 0x00, b"\x40\x30"), "", "0x3040 RS304MD: known, fine"),
        (encode_read(3, 0x00, 4), "", ""), (ret(3, 0x00, bytes.fromhex("0C30 0100")), "M005", "in a wider read too"),
    ]),
    "B001": ("a host that does not wait for the return", [
        (0.000, READ1, "", ""), (0.0009, RET1, "", "answered 0.2 ms later: fine"),
        (0.010, READ1, "", "no answer before ..."), (0.0110, encode_read(2, 0x2A, 2), "B001", "... this poll, 0.3 ms later"),
        (0.0118, ret(2, 0x2A, POS), "", ""),
        (0.020, READ1, "B002", "no answer, and the next poll comes 80 ms later: the servo's fault"),
        (0.100, encode_read(2, 0x2A, 2), "", ""), (0.1008, ret(2, 0x2A, POS), "", ""),
    ]),
    "B002": ("requests nobody answers", [
        (READ1, "B002", ""), (encode_read(2, 0x2A, 2), "", ""), (ret(2, 0x2A, POS), "", ""),
        (w(3, 0x24, b"\x01", 0x01), "B002", "write asking for an ACK"), (READ1, "", ""), (RET1, "", ""),
        (encode_read(4, 0x2A, 2), "B002", ""), (goal(1, 900), "", "the next request: no reply came"),
        (encode_read(5, 0x2A, 2), "", "the capture ends here: its reply may still have come"),
    ]),
    "B003": ("replies nobody asked for", [
        (goal(1, 900), "", ""), (RET1, "B003", ""), (b"\x07", "F002", "an ACK byte without an ACK request is noise"),
        (READ1, "", ""), (RET1, "", ""),
    ]),
    "B004": ("a return from the wrong ID", [(READ1, "", ""), (ret(2, 0x2A, POS), "B004", ""), (READ1, "", ""), (RET1, "", "")]),
    "B005": ("a return of the wrong range", [
        (READ1, "", ""), (ret(1, 0x2C, b"\x00\x00"), "B005", "address 44"),
        (READ1, "", ""), (ret(1, 0x2A, bytes(4)), "B005", "4 bytes"),
        (POLL, "", ""), (ret(1, 42, STATUS), "", "42-59 for flag 09: fine"),
        (w(1, 0x24, b"\x01", 0x01), "", "write with ACK ..."), (RET1, "B005", "... answered with a return"),
    ]),
    "B006": ("replies late or early", [
        (0.000, READ1, "", ""), (0.0008, RET1, "", "0.1 ms: fine"),
        (0.010, READ1, "", ""), (0.0206, RET1, "B006", "10 ms late"),
        (0.030, w(1, 0x07, bytes((100,))), "", "return_delay 100: 5.1 ms"),
        (0.040, READ1, "", ""), (0.0458, RET1, "", "5.1 ms: fine now"),
    ]),
    "B007": ("frames that start inside another", [
        (POLL[:6], "F003", "a poll cut off ..."), (ret(1, 42, STATUS), "B007 B003", "... by a return starting inside it"),
        (READ1, "", ""), (RET1, "", ""),
    ]),
    "B008": ("a NACK", [
        (w(1, 0x1E, POS, 0x01), "", ""), (b"\x08", "B008", ""), (w(1, 0x1E, POS, 0x01), "", ""), (b"\x07", "", "ACK: fine"),
    ]),
    "B009": ("two servos answer to one ID", [
        (0.000, READ1, "", ""), (0.0008, RET1, "", ""), (0.0019, ret(1, 0x2A, b"\x80\x03"), "B009", "ID 1 again, in the window"),
        (0.010, READ1, "", ""), (0.0108, RET1, "", ""),
        (0.0908, ret(3, 0x2A, POS), "B003", "ID 3, 80 ms later: past the window, and not the ID asked"),
        (0.100, READ1, "", ""), (0.1008, RET1, "", ""),
        (0.1808, RET1, "B003", "ID 1 again, 80 ms later: past the window, no second reply"),
        (0.200, READ1, "", ""), (0.2008, RET1, "", ""), (0.2019, ret(3, 0x2A, POS), "B003", "ID 3 in the window: not the ID asked"),
    ]),
    "S001": ("the temperature limit trips", [
        (POLL, "", ""), (ret(1, 42, STATUS), "", ""), (POLL, "", ""), (ret(1, 42, STATUS, 0x80), "S001", ""),
        (POLL, "", ""), (ret(1, 42, STATUS, 0x80), "", "still set: said once"),
    ]),
    "S002": ("a temperature alarm", [
        (POLL, "", ""), (ret(1, 42, STATUS, 0x20), "S002", ""), (POLL, "", ""), (ret(1, 42, STATUS), "", "cleared"),
        (POLL, "", ""), (ret(1, 42, STATUS, 0x20), "S002", "set again"),
    ]),
    "S003": ("a failed flash write", [
        (encode_command(1, 0x40), "", ""), (POLL, "", ""), (ret(1, 42, STATUS, 0x08), "S003", ""),
    ]),
    "S004": ("a servo that got a bad packet", [(POLL, "", ""), (ret(1, 42, STATUS, 0x02), "S004", "")]),
    "Q001": ("baud-rate changes", [
        (w(1, 0x06, b"\x04"), "", "ID 1 to 38400 ..."), (encode_command(1, 0x40), "", ""), (encode_command(1, 0x20), "", "... applied"),
        (w(2, 0x06, b"\x04"), "Q001", "ID 2: flashed, never rebooted"), (encode_command(2, 0x40), "", ""),
        (w(3, 0x06, b"\x09"), "Q001", "ID 3: never flashed"),
        (w(4, 0x06, b"\x04"), "", "ID 4 ..."), (encode_command(4, 0x20), "Q001", "... rebooted before any flash write: lost"),
    ]),
    "Q002": ("ID changes", [
        (w(1, 0x04, b"\x05"), "", "1 -> 5 ..."), (encode_command(5, 0x40), "", "... flashed as 5: fine"),
        (w(2, 0x04, b"\x06"), "Q002", "2 -> 6 ..."), (encode_command(2, 0x40), "", "... flash sent to the old ID"),
        (encode_command(3, 0x40), "", "flashed first ..."), (w(3, 0x04, b"\x07"), "", "... then 3 -> 7 ..."),
        (encode_command(7, 0x20), "Q002", "... and rebooted: lost"), (encode_command(7, 0x40), "", "too late"),
    ]),
    "Q003": ("reboots right after a flash write", [
        (0.000, encode_command(1, 0x40), "", ""), (0.002, encode_command(1, 0x20), "Q003", "2 ms later"),
        (0.100, encode_command(2, 0x40), "", ""), (0.400, encode_command(2, 0x20), "", "300 ms later: fine"),
        (0.500, encode_command(3, 0x41), "", "flash with ACK ..."), (0.5008, b"\x07", "", ""),
        (0.502, encode_command(3, 0x20), "", "... reboot after the ACK: fine"),
    ]),
    "Q004": ("goals to a servo with torque off", [
        (w(1, 0x24, b"\x00"), "", "torque off"), (goal(1, 900), "Q004", ""), (goal(1, 800), "", "said once"),
        (w(1, 0x24, b"\x01"), "", "torque on"), (goal(1, 700), "", "fine"),
        (encode_command(1, 0x20), "", "a reboot turns torque off"), (goal(1, 600), "Q004", ""),
    ]),
    "Q005": ("torque on and goal in one packet", [
        (w(1, 0x1E, bytes.fromhex("8403 0000 00 64 01")), "Q005", ""),
        (w(1, 0x1E, bytes.fromhex("8403 0000 00 64 01")), "", "torque already on: fine"),
    ]),
    "Q006": ("goals beyond the angle limits", [
        (w(1, 0x08, (1000).to_bytes(2, "little")), "", "cw limit 100.0"), (goal(1, 1200), "Q006", ""),
        (goal(1, 900), "", ""), (w(1, 0x0A, (-500).to_bytes(2, "little", signed=True)), "", "ccw limit -50.0"),
        (goal(1, -600), "Q006", ""), (goal(2, 1200), "", "ID 2's limits are unknown"),
    ]),
    "Q007": ("moves faster than the servo can", [
        (goal(1, 0, 100), "", "to 0 in 1 s"), (goal(1, 900, 10), "Q007", "90 deg in 0.1 s"),
        (goal(1, 0, 50), "", "90 deg in 0.5 s: fine"), (goal(1, 900, 0), "", "goal_time 0: full speed, fine"),
        (POLL, "", ""), (ret(1, 42, bytes.fromhex("0000") + bytes(16)), "", "at 0 deg now"),
        (w(1, 0x20, (10).to_bytes(2, "little")), "", "goal_time 0.1 s alone"),
        (goal(1, 900), "Q007", "90 deg from the reported 0 deg, in that goal_time"),
    ]),
    "Q008": ("too many servos", [
        (encode_long(0x23, [(i, b"\x64") for i in range(1, 25)]), "", "24 servos: fine"),
        (goal(25, 0), "Q008", "the 25th"), (goal(26, 0), "", "said once"),
    ]),
    "Q009": ("torque on for a servo past its temperature limit", [
        (POLL, "", ""), (ret(1, 42, STATUS, 0x80), "S001", ""), (w(1, 0x24, b"\x01"), "Q009", ""),
        (encode_command(1, 0x20), "", "reboot"), (w(1, 0x24, b"\x01"), "", "fine after the reboot"),
        (read_model(2), "", ""), (ret(2, 0, bytes.fromhex("1030")), "", "servo 2 is an RS301CR"),
        (POLL2, "", ""), (ret(2, 42, STATUS, 0x80), "S001", ""),
        (w(2, 0x24, b"\x01"), "", "the RS301CR's way back (its manual p.20): no finding"),
    ]),
    "Q010": ("a register an RS204MD takes only with torque off, written with torque on", [
        (read_model(1), "", ""), (ret(1, 0, bytes.fromhex("4020")), "", "servo 1 is an RS204MD"),
        (w(1, 0x05, b"\x01"), "", "reverse while torque is unknown: nothing said"),
        (w(1, 0x24, b"\x01"), "", "torque on"), (w(1, 0x05, b"\x00"), "Q010", "reverse: ignored"),
        (w(1, 0x24, b"\x00"), "", "torque off"), (w(1, 0x05, b"\x00"), "", "now it takes"),
        (read_model(2), "", ""), (ret(2, 0, bytes.fromhex("3030")), "", "servo 2 is an RS303MR"),
        (w(2, 0x24, b"\x01"), "", ""), (w(2, 0x05, b"\x01"), "", "an RS303MR takes it with torque on"),
    ]),
}


def write() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for old in OUT.glob("*.*hex"):
        old.unlink()
    for code, (title, lines) in CASES.items():
        r = RULES[code]
        timed = len(lines[0]) == 4
        path = OUT / f"{code}-{r.name}.{'thex' if timed else 'hex'}"
        out = [f"# {code} {r.name}: {title}.", "# Written by tests/lint/make_captures.py; `# expect:` lists the findings of each frame."]
        for item in lines:
            t, fr, exp, note = item if timed else (None, *item)
            text = fr.hex(" ").upper()
            if t is not None:
                text = f"{t:.6f} {text}"
            comment = "  ".join(x for x in (note, f"expect: {exp}" if exp else "") if x)
            out.append(f"{text:<60} # {comment}" if comment else text)
        path.write_text("\n".join(out) + "\n")


if __name__ == "__main__":
    write()
