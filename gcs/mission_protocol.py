"""The MAVLink mission protocol, ground side (mavlink.io/en/services/mission.html).

Upload: MISSION_COUNT -> the vehicle asks for each item (MISSION_REQUEST_INT, or
the legacy MISSION_REQUEST that ArduPilot still sends; both are answered with
MISSION_ITEM_INT) -> MISSION_ACK. Download: MISSION_REQUEST_LIST -> MISSION_COUNT
-> MISSION_REQUEST_INT per item -> MISSION_ACK. Clear: MISSION_CLEAR_ALL ->
MISSION_ACK. Whoever waits re-sends its last message after 1.5 s, up to 5 times,
as the spec recommends; every MAV_MISSION_RESULT error is reported by name.

ArduPilot answers an upload in the first second after boot with
MAV_MISSION_NO_SPACE ("Only 0 items are supported"); that is retried after a
short wait. What a read-back keeps is the firmware's (`autopilots` profile,
``read_back``: ArduPilot's item 0 is home and reads back as the real home, its
commands without a position come back in frame 0, and it keeps only the params
each command stores); a read-back is compared with what the firmware keeps of
what was sent, and any difference there is an error.

Only a checked mission is sent: `upload` and `upload_verified` take a
`missions.check.CheckedMission` (made only by the mission check) checked for
the vehicle's own firmware, and refuse anything else before a byte goes out.
"""

import math
import time

from gcs.mavlink import M, mission_result_name, profile_of

TIMEOUT_S = 1.5
RETRIES = 5
NO_SPACE_WAIT_S = 1.0          # ArduPilot refuses uploads for about a second after boot
NO_SPACE_RETRIES = 5
ERROR_WAIT_S = 1.0             # before trying again an upload refused with MAV_MISSION_ERROR
ITEM_TYPES = ("MISSION_ITEM_INT", "MISSION_ITEM")
REQUEST_TYPES = ("MISSION_REQUEST_INT", "MISSION_REQUEST")


class MissionError(Exception):
    """A mission transfer failed: names the vehicle, the step, and the MAV_MISSION_RESULT.
    ``capacity``: with NO_SPACE, the items the vehicle said it holds (None: unsaid)."""

    def __init__(self, vehicle, problem: str, result: int | None = None, timeout=False,
                 capacity: int | None = None):
        self.sysid = getattr(vehicle, "sysid", vehicle)
        self.result = result
        self.result_name = None if result is None else mission_result_name(result)
        self.timeout = timeout
        self.capacity = capacity
        super().__init__(f"vehicle {self.sysid}: {problem}")


class _NoSpace(Exception):
    def __init__(self, capacity: int | None = None):
        self.capacity = capacity


# -- the gate ----------------------------------------------------------------------------
def _gate(link, mission) -> list:
    """The items of a `CheckedMission` for this vehicle; TypeError for anything else,
    MissionError when it was checked for another firmware than the vehicle's (a
    home item is not flown by one and flown by the other)."""
    from missions.check import CheckedMission

    if not isinstance(mission, CheckedMission):
        raise TypeError(f"only a checked mission is uploaded (missions.check.checked), "
                        f"got {type(mission).__name__}")
    vehicle = getattr(link, "profile", None)
    flavour = getattr(link, "flavour", None)
    if vehicle is None and flavour is not None:
        vehicle = profile_of(flavour)
    if vehicle is not None and vehicle.name != mission.firmware:
        raise MissionError(link, f"{mission.name} was checked for {mission.firmware}, the "
                                 f"vehicle is {vehicle.name}: not uploaded")
    if vehicle is None and flavour is not None and profile_of(mission.firmware).home_item:
        raise MissionError(link, f"{mission.name} has a home item ({mission.firmware}), and "
                                 f"the vehicle's autopilot ({flavour}) may fly it: not uploaded")
    return mission.items


# -- upload ----------------------------------------------------------------------------
def upload(link, mission, progress=None, mission_type=M.MAV_MISSION_TYPE_MISSION,
           timeout_s=TIMEOUT_S, retries=RETRIES) -> None:
    """Upload ``mission`` (a `missions.check.CheckedMission`) to the vehicle `link`.

    progress(done, total) is called as items are sent. Raises MissionError."""
    items = _gate(link, mission)
    _transfer(link, items, progress, mission_type, timeout_s, retries)


def _transfer(link, items, progress, mission_type, timeout_s, retries) -> None:
    """The upload transfer of `items` (seq 0..n-1), with ArduPilot's NO_SPACE right
    after boot retried; a vehicle that refuses for want of space has its capacity
    noted (`known_capacity`)."""
    for k, item in enumerate(items):
        if item.seq != k:
            raise ValueError(f"mission items must be numbered 0..{len(items) - 1}: "
                             f"item {k} has seq {item.seq}")
    for attempt in range(NO_SPACE_RETRIES + 1):
        try:
            _upload_once(link, items, progress, mission_type, timeout_s, retries)
            if mission_type == M.MAV_MISSION_TYPE_MISSION:
                _note_fits(link, len(items))
            return
        except _NoSpace as refused:
            # after boot ArduPilot says NO_SPACE ("Only 0 items") for a while; past
            # its capacity always, and says how many it holds
            said = refused.capacity
            if said == 0 and attempt < NO_SPACE_RETRIES:
                time.sleep(NO_SPACE_WAIT_S)
                continue
            if said and mission_type == M.MAV_MISSION_TYPE_MISSION:
                _note_capacity(link, said)
            raise MissionError(link, f"upload of {len(items)} items refused: "
                                     f"{mission_result_name(M.MAV_MISSION_NO_SPACE)}"
                                     f"{_capacity(link, len(items), said)}",
                               M.MAV_MISSION_NO_SPACE, capacity=said or None) from None


def _upload_once(link, items, progress, mission_type, timeout_s, retries) -> None:
    count = len(items)
    link.flush(REQUEST_TYPES + ("MISSION_ACK", "STATUSTEXT"))
    sent = {"last": None}          # what to re-send on a timeout: None = the count

    def resend():
        if sent["last"] is None:
            link.send("MISSION_COUNT", count=count, mission_type=mission_type)
        else:
            _send_item(link, items[sent["last"]], mission_type)

    resend()
    highest, tries = -1, 0
    same_type = _of_type(mission_type)
    while True:
        msg = link.recv(REQUEST_TYPES + ("MISSION_ACK",), timeout_s, same_type)
        if msg is None:
            tries += 1
            if tries > retries:
                waited = "MISSION_COUNT" if sent["last"] is None else f"item {sent['last']}"
                raise _timeout(link, f"no answer to {waited} of an upload of {count} "
                                     f"items", timeout_s, retries)
            resend()
            continue
        if msg.get_type() == "MISSION_ACK":
            if msg.type == M.MAV_MISSION_ACCEPTED:
                if count == 0 or highest == count - 1:
                    if progress:
                        progress(count, count)
                    return
                continue                         # a stale ACK of an earlier transfer
            if msg.type == M.MAV_MISSION_NO_SPACE and highest < 0:
                raise _NoSpace(_capacity_said(link))
            if msg.type == M.MAV_MISSION_INVALID_SEQUENCE and highest >= 0:
                # an item it did not ask for now (our re-send crossed its next
                # request): ArduPilot says so and keeps the transfer open
                continue
            where = f"after item {highest}" if highest >= 0 else "at MISSION_COUNT"
            more = _capacity(link, count) if msg.type == M.MAV_MISSION_NO_SPACE else ""
            raise MissionError(link, f"upload of {count} items refused {where}: "
                                     f"{mission_result_name(msg.type)}{more}{_said(link)}",
                               msg.type)
        if not 0 <= msg.seq < count:
            continue                             # not a request we can answer
        tries = 0
        sent["last"] = msg.seq
        _send_item(link, items[msg.seq], mission_type)
        if msg.seq > highest:
            highest = msg.seq
            if progress:
                progress(highest, count)


def _send_item(link, item, mission_type) -> None:
    fields = dict(item.to_int())
    fields.pop("target_system", None)
    fields.pop("target_component", None)
    fields["mission_type"] = mission_type
    link.send("MISSION_ITEM_INT", **fields)


# -- download --------------------------------------------------------------------------
def download(link, progress=None, mission_type=M.MAV_MISSION_TYPE_MISSION,
             timeout_s=TIMEOUT_S, retries=RETRIES) -> list:
    """The mission the vehicle holds, as a list of missions.items.MissionItem."""
    from missions.items import MissionItem

    link.flush(("MISSION_COUNT", "MISSION_ACK") + ITEM_TYPES)
    same_type = _of_type(mission_type)
    msg = _exchange(link, lambda: link.send("MISSION_REQUEST_LIST", mission_type=mission_type),
                    ("MISSION_COUNT",), same_type, "MISSION_REQUEST_LIST", timeout_s, retries)
    count = msg.count
    items = []
    for seq in range(count):
        def ask(seq=seq):
            link.send("MISSION_REQUEST_INT", seq=seq, mission_type=mission_type)

        def answer(m, seq=seq):
            return same_type(m) and (m.get_type() == "MISSION_ACK" or m.seq == seq)

        msg = _exchange(link, ask, ITEM_TYPES, answer, f"the request for item {seq} of "
                        f"{count}", timeout_s, retries)
        items.append(MissionItem.from_int(msg))
        if progress:
            progress(seq + 1, count)
    link.send("MISSION_ACK", type=M.MAV_MISSION_ACCEPTED, mission_type=mission_type)
    return items


def clear(link, mission_type=M.MAV_MISSION_TYPE_MISSION, timeout_s=TIMEOUT_S,
          retries=RETRIES) -> None:
    """Delete the vehicle's mission (MISSION_CLEAR_ALL)."""
    link.flush("MISSION_ACK")
    _exchange(link, lambda: link.send("MISSION_CLEAR_ALL", mission_type=mission_type), (),
              _of_type(mission_type), "MISSION_CLEAR_ALL", timeout_s, retries)


def _exchange(link, ask, types, condition, what, timeout_s, retries):
    """Send `ask()` until a message of `types` (or an error MISSION_ACK) answers it.

    A MISSION_ACK ACCEPTED is the answer when `types` is empty (clear)."""
    for _ in range(retries + 1):
        ask()
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            msg = link.recv(tuple(types) + ("MISSION_ACK",), left, condition)
            if msg is None:
                break
            if msg.get_type() != "MISSION_ACK":
                return msg
            if msg.type != M.MAV_MISSION_ACCEPTED:
                raise MissionError(link, f"{what} refused: {mission_result_name(msg.type)}"
                                         f"{_said(link)}", msg.type)
            if not types:
                return msg
            # an ACCEPTED left over from an earlier transfer: keep waiting
    raise _timeout(link, f"no answer to {what}", timeout_s, retries)


def _of_type(mission_type):
    return lambda m: getattr(m, "mission_type", 0) == mission_type


def _timeout(link, problem, timeout_s, retries) -> MissionError:
    text = f"{problem} after {retries + 1} tries {timeout_s:g} s apart"
    age = link.heartbeat_age() if hasattr(link, "heartbeat_age") else float("inf")
    if age > 3:
        text += f" (no HEARTBEAT for {age:.0f} s: link lost?)" if math.isfinite(age) \
            else " (no HEARTBEAT at all)"
    if getattr(link, "signs", False) and not getattr(link.ground, "signing_key", None):
        text += "; the vehicle signs its messages and ignores unsigned ones: " \
                "give --signing-key"
    return MissionError(link, text, timeout=True)


def _capacity(link, count, said=None) -> str:
    """Why NO_SPACE came: what the vehicle said it holds, or what its firmware holds
    by default."""
    if said:
        return f" (the vehicle holds {said} items)"
    found = getattr(link, "profile", None)
    capacity = getattr(found, "mission_capacity", None)
    if capacity is not None and count > capacity:
        return f" ({found.title} holds {capacity} items by default)"
    return ""


# -- capacity ----------------------------------------------------------------------------
#: wall seconds to wait for the STATUSTEXT that follows a NO_SPACE refusal
SAID_WAIT_S = 0.5


def _capacity_said(link) -> int | None:
    """The capacity the vehicle states after a NO_SPACE refusal (ArduPilot: "Only
    650 items are supported"), None when it says nothing (PX4)."""
    found = getattr(link, "profile", None)
    if found is None or not found.capacity_text or not hasattr(link, "recv"):
        return None
    msg = link.recv("STATUSTEXT", SAID_WAIT_S,
                    lambda m: found.capacity_said(m.text) is not None)
    return None if msg is None else found.capacity_said(msg.text)


def known_capacity(link) -> int | None:
    """The items this vehicle holds, once learned this flight (None: not known)."""
    return getattr(link, "mission_capacity", None)


def _note_capacity(link, capacity: int) -> None:
    try:
        link.mission_capacity = int(capacity)
    except AttributeError:
        pass


def _note_fits(link, count: int) -> None:
    """An upload of ``count`` items went through: the capacity is at least that."""
    try:
        link.mission_fits = max(getattr(link, "mission_fits", 0) or 0, int(count))
    except AttributeError:
        pass


def learn_capacity(link, refused: int, said: int | None = None,
                   timeout_s=TIMEOUT_S, retries=RETRIES) -> int:
    """How many mission items the vehicle holds, after it refused ``refused`` for
    want of space: what it said (``said``, or learned before), else found by
    asking: MISSION_COUNT probes, halving the range between the most it took
    (`mission_fits`) and the least it refused, each probe it accepts cancelled at
    once. Cached on the link for the flight.

    Only while the vehicle is held or on the ground: an accepted MISSION_COUNT
    truncates ArduPilot's stored mission (PX4 writes a new upload aside)."""
    if said:
        _note_capacity(link, said)
    known = known_capacity(link)
    if known is not None:
        return known
    low, high = max(1, getattr(link, "mission_fits", 0) or 0), int(refused)  # low fits
    if low >= high:
        low = 1
    while high - low > 1:
        middle = (low + high) // 2
        if _probe(link, middle, timeout_s, retries):
            low = middle
        else:
            high = middle
    _note_capacity(link, low)
    return low


def _probe(link, count: int, timeout_s, retries) -> bool:
    """Whether the vehicle takes an upload of ``count`` items (the upload is
    cancelled at once)."""
    mission_type = M.MAV_MISSION_TYPE_MISSION
    link.flush(REQUEST_TYPES + ("MISSION_ACK",))
    same = _of_type(mission_type)
    for _ in range(retries + 1):
        link.send("MISSION_COUNT", count=count, mission_type=mission_type)
        msg = link.recv(REQUEST_TYPES + ("MISSION_ACK",), timeout_s, same)
        if msg is None:
            continue
        if msg.get_type() == "MISSION_ACK":
            if msg.type == M.MAV_MISSION_NO_SPACE:
                return False
            raise MissionError(link, f"probe of {count} items refused: "
                                     f"{mission_result_name(msg.type)}{_said(link)}", msg.type)
        link.send("MISSION_ACK", type=M.MAV_MISSION_OPERATION_CANCELLED,
                  mission_type=mission_type)
        return True
    raise _timeout(link, f"no answer to MISSION_COUNT {count} (capacity probe)", timeout_s,
                   retries)


def _said(link) -> str:
    """The vehicle's last STATUSTEXT, which often says why (ArduPilot)."""
    texts = getattr(getattr(link, "state", None), "statustext", None)
    return f' (vehicle said: "{texts[-1][1]}")' if texts else ""


# -- verified upload -------------------------------------------------------------------
def upload_verified(link, mission, progress=None, attempts=3, timeout_s=TIMEOUT_S,
                    retries=RETRIES) -> list:
    """Upload ``mission`` (a `missions.check.CheckedMission`), read back, compare item
    by item; returns what was read back.

    progress(done, 2 * n) covers both halves. A transfer that times out is started
    again (up to `attempts` in all), as is one refused with the generic
    MAV_MISSION_ERROR after a pause; a read-back that differs is an error."""
    items = _gate(link, mission)
    n = len(items)
    up = (lambda d, t: progress(d, 2 * n)) if progress else None
    down = (lambda d, t: progress(n + d, 2 * n)) if progress else None
    for attempt in range(1, attempts + 1):
        try:
            _transfer(link, items, up, M.MAV_MISSION_TYPE_MISSION, timeout_s, retries)
            back = download(link, down, timeout_s=timeout_s, retries=retries)
            break
        except MissionError as exc:
            # a timeout, or PX4's generic MAV_MISSION_ERROR ("not accepting mission
            # items right now": busy, or its storage slow to answer under load)
            transient = exc.timeout or exc.result == M.MAV_MISSION_ERROR
            if not transient or attempt == attempts:
                raise
            if not exc.timeout:
                time.sleep(ERROR_WAIT_S)
    problems = compare(items, back, getattr(link, "profile", None)
                       or getattr(link, "flavour", None))
    if problems:
        raise MissionError(link, "mission read back differs from the upload: "
                                 + "; ".join(problems[:5])
                                 + (f" (and {len(problems) - 5} more)" if len(problems) > 5
                                    else ""))
    return back


def compare(sent, got, flavour=None) -> list:
    """Differences between two missions, one line per item (empty: the same), as
    `MissionItem.differences` judges them, on the fields the vehicle's firmware
    keeps (``flavour``: a profile or a firmware name; None compares everything)."""
    if len(sent) != len(got):
        return [f"{len(sent)} items sent, {len(got)} read back"]
    keeper = profile_of(flavour) if isinstance(flavour, str) or flavour is None else flavour
    out = []
    for a, b in zip(sent, got):
        expected = a if keeper is None else read_back(keeper, a)
        if expected is None:
            continue
        diff = expected.differences(b)
        if diff:
            out.append(f"item {a.seq}: " + ", ".join(diff))
    return out


def read_back(profile, item):
    """``item`` (missions.items.MissionItem) as ``profile``'s firmware will report
    it when read back (`autopilots.base.Autopilot.read_back`), None when it reads
    back as something else (ArduPilot's home)."""
    from types import SimpleNamespace

    from missions.items import MissionItem

    wire = profile.read_back(item.to_int())
    return None if wire is None else MissionItem.from_int(SimpleNamespace(**wire))
