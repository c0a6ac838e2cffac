"""An emulated servo of the command-type family: its model's memory map and behaviour, its packet handling,
and a simple physical model."""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from ..protocol.events import LongPacket, ShortPacket
from ..protocol.memmap import Model, default_registry
from ..protocol.wire import (
    ACK, BAUD_RATES, BROADCAST_ID, COMMAND_ADDRESS, NACK, RETURN_FLASH_WRITE_ERROR, RETURN_RECEIVED_ERROR,
    RETURN_TEMPERATURE_ALARM, RETURN_TEMPERATURE_LIMIT, encode_return)

MEMORY_SIZE = 140            # flag-0F reads reach address 139 (manual, "Direct specified address")
ROM_START, ROM_END = 4, 30   # the variable ROM area a flash write saves (table 4.6, flag bit 6)
RAM_START, RAM_END = 30, 60  # reset at every boot (table 4.9)

# Return delay: 100 us, plus 50 us per unit of register 7 (table 4.6, No. 7).
BASE_RETURN_DELAY = 100e-6
RETURN_DELAY_STEP = 50e-6
# Not in the manual: how long a servo is deaf while it writes flash or boots. Plausible figures.
FLASH_WRITE_TIME = 0.030
BOOT_TIME = 0.100

# Status flags of a return packet (table 4.4).
FLAG_TEMPERATURE_LIMIT = RETURN_TEMPERATURE_LIMIT
FLAG_TEMPERATURE_ALARM = RETURN_TEMPERATURE_ALARM
FLAG_FLASH_ERROR = RETURN_FLASH_WRITE_ERROR
FLAG_RECEIVED_ERROR = RETURN_RECEIVED_ERROR
ALARM_MARGIN = 10.0  # the alarm bit rises 10 degC below the limit (No. 50/51)

TORQUE_OFF, TORQUE_ON, TORQUE_BRAKE = 0, 1, 2
# A servo must have some speed, angle limits and a temperature limit to move and heat up. Where a model's
# sources give none (its map says unknown: the top speed, or a register without a default), the simulator
# borrows the RS303MR's (the same register by name): an assumption of the simulation, never said of the
# model (the map stays as the sources are).
ASSUMED_TOP_SPEED_S_PER_60DEG = 0.11


def baud_table(model: Model) -> dict[int, int]:
    """The model's baud-rate codes -> bit/s (its map's baud_rate table: table 4.7 for the RS303MR)."""
    try:
        table = model.register("baud_rate").table
    except KeyError:
        table = None
    return {code: int(rate) for code, rate in table.items()} if table else dict(enumerate(BAUD_RATES))


@dataclass
class Physics:
    """Electrical and thermal constants of the model (not in the manual; chosen to look like a real bus)."""

    idle_current_ma: float = 16.0        # "in suspension" (specs)
    moving_current_ma: float = 90.0      # "in operation", no load (specs)
    stall_current_ma: float = 1200.0     # holding against full load at 100 % max torque
    ma_per_deg_s: float = 0.05           # extra current with speed
    supply_v: float = 7.4
    wiring_ohm: float = 0.25             # voltage sag per ampere drawn
    ambient_c: float = 25.0
    heat_c_per_a2: float = 40.0          # steady-state rise per A^2
    thermal_tau_s: float = 120.0         # time constant of the board temperature


class Servo:
    """One servo on the bus: memory map, flash copy, and a motion / current / temperature model.

    :meth:`receive` takes a decoded request (as the servo's UART sees it) and the time its last
    byte arrived, and returns the reply bytes and their delay, or None. :meth:`advance` moves the
    physical state on to a time; replies always report the state at the moment of the request.
    """

    def __init__(self, model: Model | str | None = None, servo_id: int = 1, *, baud: int = 115200,
                 seed: int = 0, firmware: int = 0x03, position: float = 0.0, temperature: float | None = None,
                 load: float = 0.0, physics: Physics | None = None, return_delay: int = 0) -> None:
        reg = default_registry()
        if model is None:
            model = reg.default
        elif isinstance(model, str):
            model = reg.get(model)
        self.model = model
        self.physics = physics or Physics()
        self.rng = random.Random(seed * 1000 + servo_id)
        self.defaults = bytearray(MEMORY_SIZE)
        self.writable = bytearray(MEMORY_SIZE)
        borrowed = reg.default
        for r in model.registers:
            default = r.default
            if (default is None and r.name and r.name != "model_number" and r.name in borrowed.names
                    and borrowed.register(r.name).size == r.size):  # a model number no source gives stays 0
                default = borrowed.register(r.name).default
            if default is not None and r.address + r.size <= MEMORY_SIZE:
                self.defaults[r.address:r.address + r.size] = default.to_bytes(r.size, "little", signed=default < 0)
            if r.writable:
                self.writable[r.address:r.address + r.size] = b"\x01" * r.size
        self.defaults[2] = firmware  # set at production (table 4.5); the manual's example shows 0x03
        self.mem = bytearray(self.defaults)
        self.mem[4] = servo_id
        self.bauds = baud_table(model)
        codes = [code for code, rate in self.bauds.items() if rate == baud]
        if not codes:
            raise ValueError(f"an {model.name} cannot run at {baud} bit/s (its baud_rate table: "
                             f"{', '.join(f'{r:g}' for r in self.bauds.values())})")
        self.mem[6] = codes[0]
        self.mem[7] = return_delay
        self.flash = bytes(self.mem[ROM_START:ROM_END])  # what survives a reboot
        self.baud = baud            # the rate the UART runs at: changes only at boot (No. 6)
        self.ready_at = 0.0         # deaf until then (writing flash, booting)
        self.temperature_latched = False
        self.received_error = False
        self.flash_error = False
        self.load = load            # external load, 0 (free) .. 1 (stalled)
        self.pos = position * 10.0  # 0.1 deg
        self.temp = self.physics.ambient_c if temperature is None else temperature
        self.current = self.physics.idle_current_ma
        self.speed = 0.0            # deg/s
        self.last_t = 0.0
        self._move: tuple[float, float, float, float] | None = None  # (t0, from, to, duration)
        self._timed_move = False
        self._update_readings()

    # ---- registers -------------------------------------------------------------------------
    @property
    def id(self) -> int:
        return self.mem[4]  # a new ID applies as soon as it is written (No. 4)

    def raw(self, name: str) -> int:
        r = self.model.register(name)
        return int.from_bytes(self.mem[r.address:r.address + r.size], "little", signed=r.signed)

    def get(self, name: str):
        """Engineering value of a register (the same conversion the decoder uses)."""
        return self.model.register(name).convert(self.raw(name))

    def _put(self, name: str, raw: int) -> None:
        r = self.model.register(name)
        self.mem[r.address:r.address + r.size] = int(raw).to_bytes(r.size, "little", signed=r.signed)

    @property
    def return_delay(self) -> float:
        return BASE_RETURN_DELAY + RETURN_DELAY_STEP * self.mem[7]

    def status_flags(self) -> int:
        """Flags of a return packet now (table 4.4)."""
        flags = 0
        limit = self.raw("temperature_limit")
        if self.temperature_latched:
            flags |= FLAG_TEMPERATURE_LIMIT
        if self.temp >= limit - ALARM_MARGIN:
            flags |= FLAG_TEMPERATURE_ALARM
        if self.flash_error and FLAG_FLASH_ERROR in self.model.behaviour.return_flags:
            flags |= FLAG_FLASH_ERROR
        if self.received_error:
            flags |= FLAG_RECEIVED_ERROR
        return flags

    # ---- packets ---------------------------------------------------------------------------
    def receive(self, ev: ShortPacket | LongPacket, t: float) -> tuple[bytes, float] | None:
        """Act on a request whose last byte arrived at ``t``; the reply and its delay, if any."""
        if t < self.ready_at:
            return None
        self.advance(t)
        if type(ev) is LongPacket:
            if ev.checksum_ok and ev.flag == 0:
                for r in ev.records:
                    if r.vid == self.id:
                        self._write(ev.address, r.data, t)
            return None
        if ev.id != self.id and ev.id != BROADCAST_ID:
            return None
        broadcast = ev.id == BROADCAST_ID
        asks_ack = ev.wants_ack and not broadcast
        if not ev.checksum_ok:
            # Counted in the next return's flags (table 4.4 bit 1); a NACK if one was asked for.
            self.received_error = True
            return self._reply(bytes((NACK,))) if asks_ack else None
        cmds = ev.commands
        if cmds:
            # Flash, reboot and initialize need address FF, count 0 and no data, one per packet (table 4.2); the
            # RS301CR/RS302CD take a flash write and a reboot in one (their manual p.12: flag 0x60).
            together = cmds == ("flash", "reboot") and self.model.behaviour.flash_and_reboot_together
            if ev.address != COMMAND_ADDRESS or ev.count != 0 or ev.data or (len(cmds) > 1 and not together):
                self.received_error = True
                return self._reply(bytes((NACK,))) if asks_ack else None
            if together:
                self.flash = bytes(self.mem[ROM_START:ROM_END])
                self.reboot(t + FLASH_WRITE_TIME)
                return None
            cmd = cmds[0]
            if cmd == "flash":
                self.flash = bytes(self.mem[ROM_START:ROM_END])
                self.ready_at = t + FLASH_WRITE_TIME
            elif cmd == "initialize":
                self.mem[ROM_START:ROM_END] = self.defaults[ROM_START:ROM_END]
            elif cmd == "reboot":
                self.reboot(t)
                return None
            return self._reply(bytes((ACK,))) if asks_ack else None
        if ev.data:
            if ev.count != 1 or len(ev.data) != ev.length:
                self.received_error = True
                return self._reply(bytes((NACK,))) if asks_ack else None
            self._write(ev.address, ev.data, t)
        if broadcast:
            return None  # every servo would answer at once
        if asks_ack:
            return self._reply(bytes((ACK,)))
        rr = ev.read_range_in(self.model.behaviour.return_areas)  # table 4.3, and the modes its model adds (0x0D)
        if rr is None:
            return None
        address, length = rr
        if length == 0 or address + length > MEMORY_SIZE:
            self.received_error = True
            return None
        flags = self.status_flags()
        self.received_error = False  # reported once
        return self._reply(encode_return(self.id, address, bytes(self.mem[address:address + length]), flags))

    def _reply(self, data: bytes) -> tuple[bytes, float]:
        # A few microseconds of firmware jitter on top of the configured delay.
        return data, self.return_delay + self.rng.random() * 10e-6

    def reboot(self, t: float) -> None:
        """Restart: ROM from flash, RAM to defaults, the saved baud rate, the temperature latch cleared."""
        self.mem[ROM_START:ROM_END] = self.flash
        self.mem[RAM_START:RAM_END] = self.defaults[RAM_START:RAM_END]
        code = self.mem[6]
        # An undefined code: the rate the model's manual names for it (RS301CR/RS302CD: 115200, p.19), else
        # the servo keeps its rate.
        self.baud = self.bauds.get(code) or self.model.behaviour.invalid_baud_code_gives or self.baud
        self.temperature_latched = False
        self.received_error = False
        self._move = None
        self.ready_at = t + BOOT_TIME
        self._update_readings()

    def _write(self, address: int, data: bytes, t: float) -> None:
        old_torque = self.mem[36]
        old_id, old_baud = self.mem[4], self.mem[6]
        behaviour = self.model.behaviour
        # Registers some models change only while torque is off (RS204MD: ID and Reverse, p.30): kept as they were.
        kept = [(r.address, bytes(self.mem[r.address:r.address + r.size]))
                for r in map(self.model.register, behaviour.torque_off_only)] if old_torque != TORQUE_OFF else []
        end = min(address + len(data), MEMORY_SIZE)
        mem, writable = self.mem, self.writable
        for a in range(address, end):
            if writable[a]:
                mem[a] = data[a - address]
        for a, old in kept:
            mem[a:a + len(old)] = old
        # Out-of-range ID and baud codes are refused (settable ranges of No. 4 and No. 6).
        if not 1 <= mem[4] <= 127:
            mem[4] = old_id
        if mem[6] not in self.bauds and behaviour.invalid_baud_code_gives is None:
            mem[6] = old_baud  # a model that falls back at boot keeps the code it was given
        touched = range(address, end)
        torque_on = False
        if 36 in touched:
            new = mem[36]
            if new > TORQUE_BRAKE:
                mem[36] = new = old_torque
            if self.temperature_latched and new == TORQUE_ON and behaviour.recovers_by_torque_enable:
                self.temperature_latched = False  # the RS301CR/RS302CD's way back from a temperature stop (p.20)
            if self.temperature_latched and new == TORQUE_ON:
                mem[36] = TORQUE_BRAKE  # no torque until a reboot after the limit (No. 50/51)
            elif new == TORQUE_ON and old_torque != TORQUE_ON:
                # Torque on rewrites the goal to the present position, and the same packet's goal is
                # ignored (No. 30/31).
                self._put("goal_position", round(self.pos))
                self._move = None
                torque_on = True
            elif new != TORQUE_ON:
                self._move = None
        if not torque_on and mem[36] == TORQUE_ON and any(a in touched for a in (30, 31, 32, 33)):
            self._start_move(t)

    # ---- physics ---------------------------------------------------------------------------
    def _limits(self) -> tuple[int, int]:
        return self.raw("ccw_angle_limit"), self.raw("cw_angle_limit")

    def _start_move(self, t: float) -> None:
        lo, hi = self._limits()
        # Beyond an angle limit the servo stops at the limit (No. 8-11).
        goal = min(max(self.raw("goal_position"), lo), hi)
        goal_time = self.raw("goal_time") * 0.01
        # deg/s; never faster than that (No. 32/33). A model no source gives a top speed for moves as the
        # RS303MR does (0.11 s per 60 deg): the simulator needs some speed, the maps say none.
        top = 60.0 / (self.model.top_speed_s_per_60deg or ASSUMED_TOP_SPEED_S_PER_60DEG)
        dur = max(goal_time, abs(goal - self.pos) / 10.0 / top)
        self._move = (t, self.pos, float(goal), dur)
        self._timed_move = goal_time > 0
        if self._timed_move:
            self._put("present_time", 0)

    def advance(self, t: float) -> None:
        """Move the physical state on to time ``t``."""
        dt = t - self.last_t
        if dt <= 0:
            return
        ph = self.physics
        torque = self.mem[36]
        self.speed = 0.0
        mv = self._move
        if mv is not None and torque == TORQUE_ON and self.load < 1.0:
            t0, a, b, dur = mv
            frac = 1.0 if dur <= 0 else min(1.0, (t - t0) / dur)
            self.pos = a + (b - a) * frac
            if frac < 1.0:
                self.speed = (b - a) / 10.0 / dur
            if self._timed_move:
                self._put("present_time", round(min(t - t0, dur) / 0.01))
            if frac >= 1.0:
                self._move = None
        # Current: idle draw always (No. 48/49: never 0 even with torque off), more when moving or loaded.
        cur = ph.idle_current_ma
        if torque == TORQUE_ON:
            if self.speed:
                cur = ph.moving_current_ma + abs(self.speed) * ph.ma_per_deg_s
            cur += self.load * ph.stall_current_ma * self.mem[35] / 100.0
        self.current = cur
        # Board temperature: first-order lag towards ambient + heat from I^2.
        amps = cur / 1000.0
        target = ph.ambient_c + ph.heat_c_per_a2 * amps * amps
        self.temp += (target - self.temp) * (1.0 - math.exp(-dt / ph.thermal_tau_s))
        if not self.temperature_latched and self.temp > self.raw("temperature_limit"):
            # Over the limit: brake mode, and the limit flag stays until a reboot (No. 50/51).
            self.temperature_latched = True
            self.mem[36] = TORQUE_BRAKE
            self._move = None
        self.last_t = t
        self._update_readings()

    def _update_readings(self) -> None:
        rng = self.rng
        ph = self.physics
        self._put("present_position", round(self.pos))
        self._put("present_speed", round(self.speed))
        self._put("present_current", max(0, round(self.current + rng.uniform(-2, 2))))
        self._put("present_temperature", round(self.temp))
        volts = ph.supply_v - self.current / 1000.0 * ph.wiring_ohm + rng.uniform(-0.02, 0.02)
        self._put("present_voltage", round(volts * 100))
