"""Sequence rules (Q): commands that are fine alone but wrong in the order or state they come in."""

from __future__ import annotations

import numpy as np

from ...protocol.events import T_END, T_START
from ...protocol.wire import (
    BROADCAST_ID, FLAG_REBOOT as _REBOOT, FLAG_WRITE_FLASH as _FLASH, RETURN_TEMPERATURE_LIMIT, encode_command,
    encode_long, encode_read, encode_return, encode_short)
from ..batch import UNKNOWN
from ..params import DURATION, OFFSET, Measured, Message, said, said_as
from ...protocol.memmap import behaviour_of, loaded_models
from ..registry import crowded, example, models_where, rule

# A flash write or reboot still due when a timed capture ends this soon after the write that needs it
# is no finding: the capture may have stopped before it came (the seams of a capture are not faults).
ENDED_SOON = 1.0


def _deg(raw: int) -> Measured:
    """A raw angle (0.1 deg steps, table 4.9 No. 30) as the value this recording carried; the templates
    write it ``{goal:.1f}deg``."""
    return Measured(raw / 10, "deg")


def _carry(memory, lint, rec, moves) -> None:
    """The "moved" check of a rule whose memory is a dict or set keyed by servo ID: what it remembers of
    a servo follows it to the new ID (table 4.6 No. 4: the new ID holds at once)."""
    if isinstance(memory, dict):
        taken = [(new, memory.pop(old)) for old, new in moves if old in memory]  # all out first: swaps
        memory.update(taken)
    else:
        taken = [new for old, new in moves if old in memory]
        memory.difference_update([old for old, _ in moves])
        memory.update(taken)


@rule("Q001", "baud-change-not-applied", "warning", "baud_rate written without a following flash write and reboot.", f"""
## What it does
Flags a write of baud_rate (table 4.6, No. 6) to a servo that is not followed, before the end of the
capture, by a flash write and then a reboot of that servo (or of ID 255). A reboot before any flash write
settles it: the servo restarts with the rate in its flash, so the change is lost whatever follows, and
that is said at the reboot. Otherwise it is said at the end of input (or of a time segment, F010), unless
a timed capture ended less than a second after the write: the steps may have come after it stopped.
The servo is followed across a change of its ID (the flash and reboot may go to the new ID), and a
write of the rate it already has (written or read back before) needs neither.

## Why it matters
The manual says the servo keeps running at its old rate until the new value is flashed and the servo
rebooted. A host that switches its own port to the new rate right after the write loses the servo.

## Example
{example(encode_short(1, 0, 0x06, bytes((4,))), encode_command(1, _FLASH), note="the baud rate is flashed but the servo never rebooted:")}
{example(encode_short(1, 0, 0x06, bytes((4,))), encode_command(1, _REBOOT), note="a reboot before the flash write:")}
""", kinds=("target", "command", "moved", "seam", "close"), fields=("baud_rate",), state=dict, column="silent")
def baud_change_not_applied(pending, lint, rec, plan, targets):
    # pending: servo (by its current ID) -> [the baud_rate write, the step it waits for ("flash" | "reboot"),
    # the rate code, the ID it was written to]
    j = plan.index["baud_rate"]
    for sid, raws, sh in targets:
        if raws[j] == sh.baud:
            continue  # the rate it has already (the shadow is updated after the target checks): no change
        pending[sid] = [rec, "flash", raws[j], sid]


baud_change_not_applied.on("moved")(_carry)


# Q001's and Q002's messages: the rate code written and the write's offset are this recording's; the IDs and
# the missing step name the finding.
_Q001_REBOOTED = ("{rebooted} before any flash write of the baud_rate code {code} written to {who} @{offset}: "
                  "the change is lost, it keeps its old rate")
_Q001_PENDING = "baud_rate code {code} written to {who} but {why}: it keeps its old rate"
_Q002_REBOOTED = ("{rebooted} before any flash write undoes the change of ID {old} to {new} @{offset}: "
                  "the servo comes back on the ID in its flash, not {new}")
_Q002_PENDING = "ID {old} changed to {new} but no flash write to ID {new} followed: it reverts at the next power-up"


def _rebooted(sid: int) -> str:
    return "a reboot of every servo (ID 255)" if sid == BROADCAST_ID else f"a reboot of ID {sid}"


@baud_change_not_applied.on("command")
def _baud_change_flashed_or_rebooted(pending, lint, rec, ev):
    sid = ev.id
    for key in (list(pending) if sid == BROADCAST_ID else [sid, BROADCAST_ID]):
        entry = pending.get(key)
        if entry is None:
            continue
        if ev.flag & _FLASH and entry[1] == "flash":
            entry[1] = "reboot"
        if ev.flag & _REBOOT and entry[1] == "reboot":
            del pending[key]
        elif ev.flag & _REBOOT and (key == sid or sid == BROADCAST_ID):
            # Rebooted before any flash write: the servo restarts with the rate in its flash, for certain.
            # (A reboot of one servo says nothing of the others a write to ID 255 reached.)
            w, _, code, to = pending.pop(key)
            lint.emit("Q001", rec, said(_Q001_REBOOTED, {"rebooted": _rebooted(sid), "code": Measured(code),
                                                         "who": _who(to, key), "offset": Measured(w.offset, OFFSET)}),
                      sid=to)


def _who(to: int, now: int) -> str:
    return f"ID {to}" if to == now else f"ID {to} (now ID {now})"


def _left_pending(lint, rec, end_t) -> bool:
    """Whether a step still due at the end of input (or of a time segment, ending at ``end_t``) is
    missing rather than cut off: the capture ran on for ENDED_SOON after the write that needed it."""
    t1 = rec.event[T_END]
    return not (lint.timed and end_t is not None and t1 is not None and end_t - t1 < ENDED_SOON)


@baud_change_not_applied.on("close")
def _baud_change_left_pending(pending, lint, seam=None):
    end_t = lint.end_t if seam is None else seam.t_end
    for sid, (rec, stage, code, to) in pending.items():
        if not _left_pending(lint, rec, end_t):
            continue
        why = "no flash write followed" if stage == "flash" else "it was flashed but the servo was never rebooted"
        lint.emit("Q001", rec, said(_Q001_PENDING, {"code": Measured(code), "who": _who(to, sid), "why": why}), sid=to)
    if seam is not None:
        pending.clear()  # told or let go: nothing waits across a seam


baud_change_not_applied.on("seam")(_baud_change_left_pending)  # a seam ends the steps' wait as the end does


@rule("Q002", "id-change-not-persisted", "warning", "servo_id changed but never written to flash.", f"""
## What it does
Flags a write of servo_id that changes a servo's ID when no flash write to the new ID (or to ID 255)
follows before the end of the capture. A reboot of the new ID (or of ID 255) before any such flash write
settles it: the servo restarts with the ID in its flash, so the change is lost whatever follows, and that
is said at the reboot. Otherwise it is said at the end of input (or of a time segment, F010), unless a
timed capture ended less than a second after the write. A servo renumbered twice (1 to 2, then 2 to 3)
needs one flash write, to its last ID.

## Why it matters
The servo answers to its new ID at once, so everything looks fine, but the ID reverts at the next
power-up (table 4.6, No. 4). A flash write sent to the old ID after the change reaches nobody.

## Example
{example(encode_short(1, 0, 0x04, bytes((5,))), encode_command(1, _FLASH), note="ID 1 becomes 5, then the flash write goes to the old ID 1:")}
{example(encode_command(1, _FLASH), encode_short(1, 0, 0x04, bytes((2,))), encode_command(2, _REBOOT),
         note="flashed first, then ID 1 becomes 2 and is rebooted:")}
""", kinds=("target", "command", "seam", "close"), fields=("servo_id",), state=dict, column="silent")
def id_change_not_persisted(pending, lint, rec, plan, targets):
    # pending: new servo ID -> (the write that set it, the ID the servo had when last flashed, as far as known)
    j = plan.index["servo_id"]
    changes = [(sid, raws[j]) for sid, raws, _ in targets if raws[j] != sid]
    if not changes:
        return
    earlier = [pending.pop(sid, None) for sid, _ in changes]  # all out first: a long packet may swap IDs
    for (sid, new), before in zip(changes, earlier):
        origin = sid if before is None else before[1]
        if new != origin:
            pending[new] = (rec, origin)


@id_change_not_persisted.on("command")
def _id_change_flashed(pending, lint, rec, ev):
    if ev.flag & _FLASH:
        if ev.id == BROADCAST_ID:
            pending.clear()
        else:
            pending.pop(ev.id, None)
    if ev.flag & _REBOOT:
        # Rebooted with no flash write since the change: the servo restarts with the ID in its flash, for certain.
        for new in (list(pending) if ev.id == BROADCAST_ID else [ev.id] if ev.id in pending else []):
            w, old = pending.pop(new)
            lint.emit("Q002", rec, said(_Q002_REBOOTED, {"rebooted": _rebooted(ev.id), "old": old, "new": new,
                                                         "offset": Measured(w.offset, OFFSET)}), sid=old)


@id_change_not_persisted.on("close")
def _id_change_left_pending(pending, lint, seam=None):
    end_t = lint.end_t if seam is None else seam.t_end
    for new, (rec, old) in pending.items():
        if not _left_pending(lint, rec, end_t):
            continue
        lint.emit("Q002", rec, said(_Q002_PENDING, {"old": old, "new": new}), sid=old)
    if seam is not None:
        pending.clear()


id_change_not_persisted.on("seam")(_id_change_left_pending)


@rule("Q003", "reboot-too-soon-after-flash", "warning", "A reboot before the flash write had time to finish.", f"""
## What it does
Flags a reboot sent to a servo less than `flash-write-time` (default 0.1 s) after a flash write to it
ended, unless the flash write asked for an ACK and got it first. Needs timestamps.

## Why it matters
The manual asks to send the reboot only after the flash write has finished, and warns never to cut
power during one: a reboot in the middle can leave the stored settings half written.

## Example
{example((0.0, encode_command(1, _FLASH)), (0.002, encode_command(1, _REBOOT)), note="a reboot 1.3 ms after the flash write:")}
""", kinds=("command", "moved", "seam"), needs_time=True, state=dict, column="silent")
def reboot_too_soon_after_flash(flashed, lint, rec, ev):
    # flashed: servo -> (time its last flash write is done, the time that write ended, its offset)
    flag, sid = ev.flag, ev.id
    if flag & _FLASH and not flag & _REBOOT:
        reply = rec.reply
        if reply is not None and reply.kind == "ack" and reply.event[T_END] is not None:
            ready = reply.event[T_END]
        elif ev[T_END] is not None:
            ready = ev[T_END] + lint.config.flash_write_time
        else:
            return
        flashed[sid] = (ready, ev[T_END], rec.offset)
    elif flag & _REBOOT and not flag & _FLASH and ev[T_START] is not None:
        for key in (sid, BROADCAST_ID):
            entry = flashed.get(key)
            if entry is not None and ev[T_START] < entry[0]:
                lint.emit("Q003", rec, _reboot_too_soon(ev[T_START] - (entry[1] or 0), entry[2],
                                                        lint.config.flash_write_time))
                break
        flashed.pop(sid, None)


reboot_too_soon_after_flash.on("moved")(_carry)

# Q003's message: the gap and the flash write's offset are measured; the allowance is the configured
# flash-write-time, so a changed setting is a changed finding.
_Q003 = "reboot {gap} the flash write @{offset}; allow {allow:.0f} ms (or wait for its ACK)"


def _reboot_too_soon(gap: float, offset: int, allow_s: float) -> Message:
    when = f"{gap * 1e3:.1f} ms after" if gap > 0 else "right after"  # never a held clock's 0 ms or less
    return said_as(_Q003, {"gap": Measured(gap, DURATION), "offset": Measured(offset, OFFSET), "allow": allow_s * 1e3},
                   {"gap": when})


@reboot_too_soon_after_flash.on("seam")
def _flash_times_end_at_seam(flashed, lint, seam):
    flashed.clear()  # a flash write's time says nothing of a reboot on the other side of a seam


def _goal_while_torque_off_columns(told, view) -> bool:
    """Q004 on a Block: no goal_position to a servo whose torque is off and that Q004 has not named yet
    (torque_enable writes take the record path: torque stays as it was before the Block)."""
    torque = view.shadows("torque")
    for t in view.targets:
        if "goal_position" not in t.plan.index:
            continue
        ids = t.ids
        off = (torque[ids] == 0) & (ids != BROADCAST_ID)
        if off.any() and any(s not in told for s in ids[off].tolist()):
            return False
    return True


@rule("Q004", "goal-while-torque-off", "warning", "A goal position sent to a servo whose torque is off.", f"""
## What it does
Flags a goal_position write to a servo whose torque_enable the linter last saw as 0 (written or read,
or reset by a reboot). Said once per servo until its torque state changes.

## Why it matters
A servo with torque off does not move, and when torque is switched on it takes its present position
as the goal (table 4.9, No. 36): the commanded goal is lost. The usual cause is a forgotten torque-on
step after power-up or a reboot.

## Example
{example(encode_short(1, 0, 0x24, bytes((0,))), encode_short(1, 0, 0x1E, bytes.fromhex("8403")))}
""", kinds=("target", "command", "moved"), fields=("goal_position", "torque_enable"), state=set, column=_goal_while_torque_off_columns)
def goal_while_torque_off(told, lint, rec, plan, targets):
    # told: servos Q004 spoke for in their current torque-off spell; a torque_enable write or a reboot
    # ends the spell.
    idx = plan.index
    g = idx.get("goal_position")
    j = idx.get("torque_enable")
    for sid, raws, sh in targets:
        if g is not None and sh.torque == 0 and sid not in told and sid != BROADCAST_ID:
            if j is not None and raws[j] != 0:
                continue  # torque comes on in this very packet: Q005
            told.add(sid)
            lint.emit("Q004", rec, said("goal_position {goal:.1f}deg to ID {id}, whose torque is off",
                                        {"goal": _deg(raws[g]), "id": sid}), sid=sid)
        if j is not None:
            told.discard(sid)


@goal_while_torque_off.on("command")
def _torque_off_spell_rebooted(told, lint, rec, ev):
    if ev.flag & _REBOOT:
        if ev.id == BROADCAST_ID:
            told.clear()
        else:
            told.discard(ev.id)


goal_while_torque_off.on("moved")(_carry)


@rule("Q005", "torque-on-with-goal", "warning", "Torque on and a goal position in one packet.", f"""
## What it does
Flags a packet that writes goal_position and switches torque_enable to 1 at once (addresses 30-36 in
one write), for a servo whose torque was not already known to be on.

## Why it matters
The manual says the servo then turns its torque on but does not move: switching torque on copies the
present position into the goal, overwriting the goal sent in the same packet.

## Example
{example(encode_short(1, 0, 0x1E, bytes.fromhex("8403 0000 00 64 01")))}
""", kinds=("target",), fields=("torque_enable",), column="silent")
def torque_on_with_goal(lint, rec, plan, targets):
    idx = plan.index
    if "goal_position" not in idx:
        return
    for sid, raws, sh in targets:
        if raws[idx["torque_enable"]] == 1 and sh.torque != 1:
            lint.emit("Q005", rec, said("torque on and goal_position {goal:.1f}deg in one packet to ID {id}: "
                                        "the servo will not move", {"goal": _deg(raws[idx["goal_position"]]), "id": sid}),
                      sid=sid)


def _goal_beyond_angle_limit_columns(view) -> bool:
    """Q006 on a Block: no goal_position beyond the limits (limit writes take the record path)."""
    cw, ccw, rev = view.shadows("cw"), view.shadows("ccw"), view.shadows("reverse")
    for t in view.targets:
        g = t.plan.index.get("goal_position")
        if g is None:
            continue
        goal, ids = view.written(t, g), t.ids
        free = rev[ids] != 1
        over = free & (cw[ids] != UNKNOWN) & (goal > cw[ids])
        under = free & ~over & (ccw[ids] != UNKNOWN) & (goal < ccw[ids])
        if (over | under).any():
            return False
    return True


@rule("Q006", "goal-beyond-angle-limit", "warning", "A goal position beyond the servo's angle limits.", f"""
## What it does
Flags a goal_position beyond the cw_angle_limit or ccw_angle_limit the linter last saw written to or
read from that servo (table 4.6, No. 8-11). Skipped for a servo set to reverse, whose limits mirror.

## Why it matters
The servo stops at the limit (as the manual says), so the joint ends short of where the host thinks
it is; gait and kinematics computed from the commanded angle go wrong.

## Example
{example(encode_short(1, 0, 0x08, (1000).to_bytes(2, "little")), encode_short(1, 0, 0x1E, (1200).to_bytes(2, "little")),
         note="cw_angle_limit 100.0 deg, then a goal of 120.0 deg:")}
""", kinds=("target",), fields=("goal_position",), column=_goal_beyond_angle_limit_columns)
def goal_beyond_angle_limit(lint, rec, plan, targets):
    j = plan.index["goal_position"]
    for sid, raws, sh in targets:
        if sh.reverse == 1:
            continue
        g = raws[j]
        if sh.cw is not None and g > sh.cw:
            side, limit = "cw", sh.cw
        elif sh.ccw is not None and g < sh.ccw:
            side, limit = "ccw", sh.ccw
        else:
            continue
        # The limit is a register value the recording carried (written or read), so measured like the goal.
        lint.emit("Q006", rec, said("goal_position {goal:.1f}deg to ID {id} beyond its {side}_angle_limit {limit:.1f}deg",
                                    {"goal": _deg(g), "id": sid, "side": side, "limit": _deg(limit)}), sid=sid)


def too_fast(dist, top_speed_s_per_60deg, goal_time):
    """Whether moving ``dist`` (raw 0.1 deg) in ``goal_time`` (raw 10 ms) asks for more than the top speed:
    (dist/10 deg) / (goal_time/100 s) > 60 deg / top speed. For one move, or a column of them."""
    return dist * top_speed_s_per_60deg > 6 * goal_time


def _goal_time_too_fast_columns(view) -> bool:
    """Q007 on a Block: no move faster than the model's top speed, from the position and goal time each
    servo's shadow holds just before its row (Blocks follow both, row by row)."""
    for t in view.targets:
        plan = t.plan
        g = plan.index.get("goal_position")
        if g is None or plan.model.top_speed_s_per_60deg is None:  # no source gives the model's top speed
            continue
        goal, ids = view.written(t, g), t.ids
        pos = view.before_rows("pos", t.rows, ids)  # checked before the row's writes apply (its sub-order 0)
        j = plan.index.get("goal_time")
        if j is not None:
            gt = view.written(t, j)
        else:
            gt = view.before_rows("goal_time", t.rows, ids)
            gt = np.where(gt == UNKNOWN, 0, gt)
        known = (pos != UNKNOWN) & (gt != 0)
        if (known & too_fast(np.abs(goal - pos), plan.model.top_speed_s_per_60deg, gt)).any():
            return False
    return True


_Q007 = "{dist:.1f} deg in {time:.0f} ms on ID {id} asks {speed:.0f} deg/s; {model} tops out at {top:.0f} deg/s"


@rule("Q007", "goal-time-too-fast", "warning", "A move faster than the model's top speed.", f"""
## What it does
Flags a goal_position with a goal_time (same packet, or the last one written) that asks for more speed
than the model has: 60 deg in 0.11 s for the RS303MR, 0.16 s for the RS304MD (no load, 7.4 V). The
distance is from the last goal sent or position reported; goal_time 0 (as fast as possible) is fine.

## Why it matters
The servo moves at its top speed instead and arrives late (the manual says so for goal_time); a gait
that relies on the timing drifts, and the servos run hot pushing at their limit.

## Example
{example(encode_short(1, 0, 0x1E, bytes.fromhex("0000 6400")), encode_short(1, 0, 0x1E, bytes.fromhex("8403 0A00")),
         note="90 deg in 0.1 s on an RS303MR (it needs 0.165 s):")}
""", kinds=("target",), fields=("goal_position",), column=_goal_time_too_fast_columns)
def goal_time_too_fast(lint, rec, plan, targets):
    idx = plan.index
    j = idx.get("goal_time")
    g = idx["goal_position"]
    ts = plan.model.top_speed_s_per_60deg
    if ts is None:
        return  # no source gives the model's top speed: nothing to hold the move to
    for sid, raws, sh in targets:
        pos = sh.pos
        if pos is None:
            continue
        gt = raws[j] if j is not None else sh.goal_time
        if not gt:
            continue
        dist = abs(raws[g] - pos)
        if not too_fast(dist, ts, gt):
            continue
        # The move (distance, goal_time at 10 ms a step, the speed it asks) is measured; the model and its top
        # speed (the manual's 60 deg in ts seconds) name the finding.
        lint.emit("Q007", rec, said(_Q007, {"dist": Measured(dist / 10, "deg"), "time": Measured(gt / 100, DURATION),
                                            "id": sid, "speed": Measured(dist * 10 / gt, "deg/s"),
                                            "model": plan.model.name, "top": 60 / ts}), sid=sid)


@rule("Q008", "too-many-servos", "warning", "More than 24 servo IDs on one TTL bus.", f"""
## What it does
Flags the packet that brings the number of distinct servo IDs seen on the bus (requests, long-packet
VIDs, returns; not 255) above `max-servos` (default 24, chapter 3 "Systems"). Said once.

## Why it matters
The manual limits a TTL command-type bus to 24 servos and warns that more may malfunction: the line's
load and the time each poll cycle takes both grow with every servo.

## Example
{example(encode_long(0x23, [(i, bytes((100,))) for i in range(1, 26)]), note="max_torque to 25 servos in one long packet:")}
""", kinds=("short", "long", "return"), when="crowded", state=list, column="silent")
def too_many_servos(told, lint, rec, ev):
    # told: empty until Q008 has spoken (it speaks once)
    if not told and crowded(lint):
        told.append(rec)
        lint.emit("Q008", rec, said("{seen} servo IDs on the bus; a TTL bus carries at most {most}",
                                    {"seen": Measured(len(lint.ids)), "most": lint.config.max_servos}))


@rule("Q009", "torque-on-after-temperature-limit", "error", "Torque on for a servo locked by its temperature limit.", f"""
## What it does
Flags torque_enable set to 1 for a servo whose return reported the temperature limit (S001) with no
reboot of it since.

Only for models that need a reboot after the limit
({models_where(lambda m: not m.behaviour.recovers_by_torque_enable)}): on the
{models_where(lambda m: m.behaviour.recovers_by_torque_enable)} a torque_enable write is the way back (its
manual, p.20), so it is no finding there, and it ends the lock the rule remembers.

## Why it matters
The manual says a servo that reached its temperature limit refuses torque on until it is rebooted or
power-cycled: the command does nothing and the joint stays limp, while the host assumes it holds.

## Example
{example(encode_return(1, 0x2A, bytes.fromhex("8403"), flags=RETURN_TEMPERATURE_LIMIT), encode_short(1, 0, 0x24, bytes((1,))))}
""", kinds=("target",), fields=("torque_enable",), column="silent")
def torque_on_after_temperature_limit(lint, rec, plan, targets):
    j = plan.index["torque_enable"]
    if behaviour_of(plan.model).recovers_by_torque_enable:
        for _, _, sh in targets:
            sh.temp_limit = False  # this model's way back from a temperature stop
        return
    for sid, raws, sh in targets:
        if sh.temp_limit and raws[j] == 1:
            lint.emit("Q009", rec, said("torque on for ID {id}, which tripped its temperature limit and was not "
                                        "rebooted since", {"id": sid}), sid=sid)



def _torque_off_only_fields() -> tuple[str, ...]:
    """Every register some model takes only with torque off (its map's [behaviour] torque_off_only): the writes
    Q010 looks at. With none (no such model loaded) servo_id stands in: no fields at all would mean every write."""
    return tuple(sorted({name for m in loaded_models() for name in m.behaviour.torque_off_only})) or ("servo_id",)


def _needs_torque_off(plan) -> list[str]:
    """The registers of this write that its model changes only with torque off."""
    off = behaviour_of(plan.model).torque_off_only
    return [name for name in off if name in plan.index]


def _write_needs_torque_off_columns(view) -> bool:
    """Q010 on a Block: no write of a torque-off-only register to a servo whose torque is known to be on
    (torque_enable writes take the record path: torque stays as it was before the Block)."""
    torque = view.shadows("torque")
    for t in view.targets:
        if _needs_torque_off(t.plan):
            on = (torque[t.ids] != 0) & (torque[t.ids] != UNKNOWN)
            if on.any():
                return False
    return True


@rule("Q010", "write-needs-torque-off", "warning", "A register written while torque is on, which its model takes only with torque off.", f"""
## What it does
Flags a write to a register that the servo's model changes only while its torque is off, to a servo whose
torque_enable the linter last saw on or in brake mode. The models' maps name these registers: servo_id and
reverse on the RS204MD (its manual, p.30); models: {models_where(lambda m: bool(m.behaviour.torque_off_only))}.

## Why it matters
The servo ignores the write and keeps its old ID or direction, while the host goes on as if it had
changed: the next packets go to an ID nobody answers to, or the joint turns the wrong way.
Switch torque off (torque_enable 0), write, then switch it back on. (The linter's other rules and the
pairing still take such a write as done: a servo_id write moves the servo to its new ID for them.)

## Example
{example(encode_read(1, 0, 2), encode_return(1, 0, bytes.fromhex("4020")),
         encode_short(1, 0, 0x24, bytes((1,))), encode_short(1, 0, 0x05, bytes((1,))),
         note="servo 1 answers model number 0x2040 (RS204MD); torque on, then reverse:")}
""", kinds=("target",), fields=_torque_off_only_fields(), column=_write_needs_torque_off_columns)
def write_needs_torque_off(lint, rec, plan, targets):
    for name in _needs_torque_off(plan):
        for sid, _, sh in targets:
            if sh.torque is not None and sh.torque != 0 and sid != BROADCAST_ID:
                lint.emit("Q010", rec, said("{name} written to ID {id} ({model}) while its torque is on: "
                                            "the {model} takes it only with torque off",
                                            {"name": name, "id": sid, "model": plan.model.name}), sid=sid)
