"""Scripted hosts: a hexapod gait, a setup session, and faults that the linter should catch."""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from collections.abc import Callable, Generator, Iterator

from ..protocol.memmap import bus_rates
from ..protocol.wire import (
    FLAG_REBOOT, FLAG_WRITE_FLASH, RETURN_ACK, RETURN_MODE_RANGES, encode_command, encode_long,
    REQUEST_FIRST, RETURN_FIRST, encode_read, encode_short)
from .bus import Chunk, SimBus
from .servo import RETURN_DELAY_STEP, Physics, Servo

CYCLE = 0.020          # 50 Hz goal updates (longer where the baud rate cannot carry them)
POLL_MODE = 0x09       # return of addresses 42-59 (table 4.3)
POLL_REPLY_BYTES = 8 + RETURN_MODE_RANGES[POLL_MODE][1]
HOST_TIMEOUT = 0.060   # a careful host waits longer than the sniffer's 50 ms reply timeout


class Host:
    """What a robot controller does on the bus, as calls: polls, reads, writes, long packets."""

    def __init__(self, bus: SimBus, rng: random.Random) -> None:
        self.bus = bus
        self.rng = rng

    def request(self, packet: bytes, timeout: float = HOST_TIMEOUT) -> bool:
        """Send a request that asks for a reply and wait for it (or for the timeout); True if answered."""
        replies = self.bus.send(packet)
        if replies:
            self.bus.wait_quiet()
            return True
        self.bus.sleep(timeout)
        return False

    def poll(self, sid: int) -> bool:
        # Flag 09 with address 0, length 0, count 1: the manual's own example (No. 42/43).
        return self.request(encode_short(sid, POLL_MODE, 0, b"", length=0, count=1))

    def read(self, sid: int, address: int, length: int) -> bool:
        return self.request(encode_read(sid, address, length))

    def write(self, sid: int, address: int, data: bytes, *, ack: bool = False) -> bool:
        if ack:
            return self.request(encode_short(sid, RETURN_ACK, address, data))
        self.bus.send(encode_short(sid, 0, address, data))
        return True

    def command(self, sid: int, flag: int) -> None:
        self.bus.send(encode_command(sid, flag))

    def long(self, address: int, records: list[tuple[int, bytes]]) -> None:
        self.bus.send(encode_long(address, records))


@dataclass
class Scenario:
    """A named bus: the servos on it and the host script that drives them."""

    name: str
    summary: str
    build: Callable[[SimBus, random.Random, float], Iterator[None]]
    duration: float                 # default length in simulated seconds
    expects: tuple[str, ...] = ()   # lint codes the scenario exists to trigger (empty: lints clean)
    servos: int = 0


SCENARIOS: dict[str, Scenario] = {}


def scenario(name: str, summary: str, duration: float, expects: tuple[str, ...] = (), servos: int = 0):
    def deco(fn):
        SCENARIOS[name] = Scenario(name, summary, fn, duration, expects, servos)
        return fn
    return deco


def run(name: str, *, baud: int = 115200, seed: int = 0, duration: float | None = None,
        bus: SimBus | None = None) -> Generator[Chunk, None, None]:
    """The capture of a scenario as ``(bytes, t)`` chunks (t in seconds from 0), lazily."""
    sc = get(name)
    if baud not in bus_rates():
        raise ValueError(f"the servos cannot run at {baud} bit/s (their tables: {', '.join(map(str, bus_rates()))})")
    bus = bus or SimBus(baud)
    rng = random.Random(seed)
    script = sc.build(bus, rng, sc.duration if duration is None else duration)
    for _ in script:
        yield from bus.drain()
    yield from bus.drain(final=True)


def get(name: str) -> Scenario:
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"unknown scenario {name!r} (known: {', '.join(SCENARIOS)})") from None


# ---- the gait shared by the hexapod and the fault scenarios -------------------------------------
@dataclass
class Gait:
    """A tripod-like sine gait: goal positions to every servo by long packet, then round-robin polls."""

    ids: list[int]
    amplitude: float = 25.0       # deg
    period: float = 1.2           # s
    polls: bool = True
    next_poll: int = 0
    hold: dict[int, float] = field(default_factory=dict)  # servos held at a fixed angle (goal time 0)

    def angle(self, sid: int, t: float) -> float:
        if sid in self.hold:
            return self.hold[sid]
        return self.amplitude * math.sin(2 * math.pi * t / self.period + sid * math.pi / 3)

    def goals(self, t: float, goal_time: float) -> list[tuple[int, bytes]]:
        units = round(goal_time / 0.01)
        return [(sid, round(self.angle(sid, t) * 10).to_bytes(2, "little", signed=True)
                 + (0 if sid in self.hold else units).to_bytes(2, "little")) for sid in self.ids]


def _startup(host: Host, gait: Gait) -> Iterator[None]:
    """Read every servo's model number, switch torque on, and stand up slowly."""
    bus = host.bus
    for sid in gait.ids:
        host.read(sid, 0, 2)  # model number (table 4.5): the sniffer learns each servo's model from it
        yield
    host.long(36, [(sid, b"\x01") for sid in gait.ids])  # torque on (No. 36)
    # First pose over one second: a jump there in 20 ms would be faster than the servo can go.
    host.long(30, gait.goals(bus.t + 1.0, 1.0))
    bus.sleep(1.0)
    yield


def cycle_time(bus: SimBus, servos: int) -> float:
    """20 ms (50 Hz) when the goals' long packet fits with room for polls; longer on a slow bus."""
    long_time = (8 + 5 * servos) * bus.bt
    return max(CYCLE, math.ceil(2 * long_time / 0.01) * 0.01)


def _cycles(host: Host, gait: Gait, duration: float, hook: Callable[[int], None] | None = None) -> Iterator[None]:
    """Goal cycles until ``duration``: one long packet of goals, then as many polls as fit.

    A cycle the host misses (it was waiting for a reply that never came) is skipped, and the gait
    waits for it: each goal is one gait step from the last, so no step asks for more speed.
    """
    bus = host.bus
    bt = bus.bt
    period = cycle_time(bus, len(gait.ids))
    poll_cost = (8 + POLL_REPLY_BYTES) * bt + 200e-6 + 2 * bus.turnaround
    cycle = 0
    t0 = phase = bus.t
    while True:
        start = t0 + cycle * period
        if bus.t > start + 1e-9:
            cycle = math.ceil((bus.t - t0) / period - 1e-9)
            continue
        if start >= duration:
            return
        bus.sleep_until(start)
        phase += period
        host.long(30, gait.goals(phase, period))
        if hook is not None:
            hook(cycle)
        end = start + period - 100e-6
        while gait.polls and gait.ids and bus.t + poll_cost < end:
            sid = gait.ids[gait.next_poll % len(gait.ids)]
            gait.next_poll += 1
            if not host.poll(sid):
                break  # the host waited its timeout: this cycle is over
        cycle += 1
        yield


def _servos(bus: SimBus, ids, seed: int, models=("RS303MR",), **kw) -> list[Servo]:
    return [bus.attach(Servo(models[k % len(models)], sid, baud=bus.baud, seed=seed, **kw))
            for k, sid in enumerate(ids)]


def _seed(rng: random.Random) -> int:
    return rng.randrange(1 << 30)


# ---- healthy ------------------------------------------------------------------------------------
@scenario("hexapod", "18 servos: long-packet goals at 50 Hz, round-robin polls of 42-59", 10.0, servos=18)
def hexapod(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    ids = list(range(1, 19))
    # Coxa joints are the lighter RS304MD, femur and tibia RS303MR.
    _servos(bus, ids, _seed(rng), models=("RS304MD", "RS303MR", "RS303MR"))
    host, gait = Host(bus, rng), Gait(ids)
    yield from _startup(host, gait)
    yield from _cycles(host, gait, duration)


@scenario("setup", "provision three new servos one at a time: read model, set ID and baud, flash, reboot", 3.0,
          servos=3)
def setup(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    host = Host(bus, rng)
    seed = _seed(rng)
    for k, model in enumerate(("RS303MR", "RS304MD", "RS303MR")):
        new_id = 10 + k
        servo = bus.attach(Servo(model, 1, baud=bus.baud, seed=seed + k))  # factory default: ID 1 (No. 4)
        code = servo.mem[6]
        bus.sleep(0.2)
        host.write(1, 0, b"", ack=True)            # ping: is anyone at ID 1?
        host.request(encode_short(1, 0x03))       # read 0-29: model number, firmware, ROM settings
        host.write(1, 4, bytes((new_id,)))         # new ID: effective at once (No. 4)
        host.write(new_id, 6, bytes((code,)), ack=True)  # baud rate code, applied after flash + reboot (No. 6)
        host.command(new_id, FLAG_WRITE_FLASH)     # save 4-29 to flash (table 4.2 bit 6)
        bus.sleep(0.15)                            # let the flash write finish before the reboot
        host.command(new_id, FLAG_REBOOT)          # a separate packet, as the manual asks
        bus.sleep(0.3)
        host.request(encode_short(new_id, 0x03))   # read back: the ID survived the reboot
        yield


# ---- faults -------------------------------------------------------------------------------------
FAULT_IDS = list(range(1, 7))


def _fault_bus(bus: SimBus, rng: random.Random, **kw) -> tuple[Host, Gait, list[Servo]]:
    servos = _servos(bus, FAULT_IDS, _seed(rng), **kw)
    return Host(bus, rng), Gait(list(FAULT_IDS)), servos


@scenario("noise", "6 servos; bursts of noise bytes on the idle line (a loose ground, a motor's EMI)", 3.0,
          expects=("F002",), servos=6)
def noise(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    host, gait, _ = _fault_bus(bus, rng)
    yield from _startup(host, gait)
    # No FA or FD in the noise, so it never looks like a header: it is just garbage.
    pool = [b for b in range(256) if b not in (REQUEST_FIRST, RETURN_FIRST)]

    def hook(cycle: int) -> None:
        if cycle % 10 == 5:
            bus.wait_quiet()
            bus.sleep(200e-6)
            bus.inject(bytes(rng.choice(pool) for _ in range(rng.randint(2, 9))))
            bus.sleep(40 * bus.bt)  # the glitch ends well before the host talks again
    yield from _cycles(host, gait, duration, hook)


@scenario("silent-servo", "6 servos; servo 4 is commanded and polled but never answers (a broken wire)", 3.0,
          expects=("B002",), servos=6)
def silent_servo(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    host, gait, servos = _fault_bus(bus, rng)
    bus.detach(servos[3])
    yield from _startup(host, gait)
    yield from _cycles(host, gait, duration)


@scenario("duplicate-id", "6 servos plus a seventh left at ID 2: two returns to every poll of ID 2", 3.0,
          expects=("B009",), servos=7)
def duplicate_id(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    host, gait, _ = _fault_bus(bus, rng)
    # The twin answers later (its return delay was raised), so the two returns follow each other
    # instead of colliding: what a sniffer on a real bus usually sees.
    # Below about 57600 baud even the longest delay (255 units, 12.85 ms) is too short, and they collide.
    delay = min(255, math.ceil((POLL_REPLY_BYTES * bus.bt + 300e-6) / RETURN_DELAY_STEP))
    twin = Servo("RS303MR", 2, baud=bus.baud, seed=_seed(rng), return_delay=delay)
    bus.attach(twin)
    yield from _startup(host, gait)
    yield from _cycles(host, gait, duration)


@scenario("request-before-return", "6 servos; now and then the host writes to servo 1 before servo 5's "
          "return has come", 3.0, expects=("B001",), servos=6)
def request_before_return(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    host, gait, servos = _fault_bus(bus, rng)
    # Servo 5 is set to answer late (return delay 2.1 ms or more, No. 7), so a short write fits in
    # before its return. The host sets it on the bus, so a sniffer knows the delay to expect.
    delay = max(40, math.ceil((9 * bus.bt + 400e-6) / RETURN_DELAY_STEP))
    host.write(5, 7, bytes((delay,)))
    yield from _startup(host, gait)

    def hook(cycle: int) -> None:
        if cycle % 10 == 3:
            bus.send(encode_short(5, POLL_MODE, 0, b"", length=0, count=1))
            bus.sleep(100e-6)
            # The host does not wait for the return before its next request.
            bus.send(encode_short(1, 0, 35, b"\x64"), wait=False)
            bus.wait_quiet()
    yield from _cycles(host, gait, duration, hook)


@scenario("bad-checksum", "6 servos; every half second a goal write goes out with a wrong checksum", 3.0,
          expects=("F001", "S004"), servos=6)
def bad_checksum(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    host, gait, _ = _fault_bus(bus, rng)
    yield from _startup(host, gait)

    def hook(cycle: int) -> None:
        if cycle % 25 == 7:
            sid = gait.ids[(cycle // 25) % len(gait.ids)]
            pkt = bytearray(encode_short(sid, 0, 35, b"\x64"))  # max torque 100 %, but corrupted
            pkt[-1] ^= 0x5A
            bus.send(bytes(pkt))
    yield from _cycles(host, gait, duration, hook)


@scenario("overheat", "6 servos; servo 2 is stalled against an obstacle and heats up to its limit, and "
          "the host keeps switching torque back on", 8.0, expects=("S002", "S001", "Q009"), servos=6)
def overheat(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    host, gait, servos = _fault_bus(bus, rng)
    hot = servos[1]
    # Already warm and thermally fast, so the limit (77 degC by default, No. 14/15) comes within seconds.
    hot.physics = Physics(thermal_tau_s=3.0)
    hot.temp = 62.0
    hot.load = 1.0
    gait.hold[2] = 30.0  # a gripper squeezing: "as fast as you can" (goal time 0), and it cannot get there
    yield from _startup(host, gait)

    def hook(cycle: int) -> None:
        if cycle % 50 == 49:
            host.long(36, [(sid, b"\x01") for sid in gait.ids])  # a naive host re-enables torque
    yield from _cycles(host, gait, duration, hook)


# ---- the family ---------------------------------------------------------------------------------
@scenario("family", "a mixed-family TTL bus: RS303MR, RS304MD and RS204MD servos, each known by its model "
          "number; the host reverses an RS204MD while its torque is on", 4.0, expects=("Q010",), servos=6)
def family(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    ids = list(range(1, 7))
    _servos(bus, ids, _seed(rng), models=("RS303MR", "RS304MD", "RS204MD"))
    host, gait = Host(bus, rng), Gait(ids)
    yield from _startup(host, gait)  # reads each servo's model number: the sniffer picks each one's map

    def hook(cycle: int) -> None:
        if cycle == 40:
            # The RS204MD takes Reverse only with torque off (its manual, p.30): this write changes nothing.
            host.write(3, 5, b"\x01")
    yield from _cycles(host, gait, duration, hook)


@scenario("rs485-family", "an RS485 bus of RS301CR and RS302CD servos: model numbers read, a return delay "
          "saved with flash and reboot in one packet (flag 0x60, as their manual allows)", 3.0, servos=6)
def rs485_family(bus: SimBus, rng: random.Random, duration: float) -> Iterator[None]:
    ids = list(range(1, 7))
    _servos(bus, ids, _seed(rng), models=("RS301CR", "RS302CD"))
    host, gait = Host(bus, rng), Gait(ids)
    yield from _startup(host, gait)

    def hook(cycle: int) -> None:
        if cycle == 20:
            bus.wait_quiet()
            host.write(2, 7, b"\x02")                        # return delay 200 us (No. 7)
            host.command(2, FLAG_WRITE_FLASH | FLAG_REBOOT)   # saved and rebooted in one packet (their p.12)
            bus.sleep(0.2)                                   # the flash write and the boot
            host.write(2, 36, b"\x01")                       # torque is off after a boot (RAM defaults)
    yield from _cycles(host, gait, duration, hook)
