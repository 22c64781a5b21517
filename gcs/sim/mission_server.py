"""The vehicle side of the MAVLink mission protocol (mavlink.io/en/services/mission.html).

Upload: MISSION_COUNT -> item requests (re-sent after 1.5 s, up to 5 times) ->
MISSION_ACK. Download: MISSION_REQUEST_LIST -> MISSION_COUNT -> the items asked
for. ArduPilot quirks, when its flavour says so: items are requested with the
legacy MISSION_REQUEST, an upload in the first second after boot is refused with
MAV_MISSION_NO_SPACE, item 0 is home and always reads back as the real home, and
items are written into the live mission as they arrive (uploads are not atomic).
Items are stored as the firmware's profile says it keeps them (`read_back`:
ArduPilot's DO commands in frame 0, only the params each command stores), so
a download returns what the real autopilot would. A mission longer than the
vehicle's capacity (the profile's: ArduPilot 650, PX4 none; or as configured)
is refused with NO_SPACE at MISSION_COUNT, with the STATUSTEXT ArduPilot sends.
PX4 requests with MISSION_REQUEST_INT and swaps the mission in when complete.

Rally points and fence items (MAV_MISSION_TYPE_RALLY, _FENCE: what a ground
station such as QGroundControl uploads from a ``.plan`` beside its mission) are
taken by the same protocol and kept as sent, each list apart (`other`): both
firmwares hold them, and a ground station that finds them refused calls the whole
upload failed. The vehicle's return reads the rally points (`rally`).
"""

from dataclasses import dataclass, replace

from pymavlink.dialects.v20 import ardupilotmega as mavlink

# GLOBAL_FRAMES is also taken from here (gcs.sim.vehicle)
from autopilots.mavlink import FRAME_MISSION, GLOBAL_FRAMES

SUPPORTED_FRAMES = GLOBAL_FRAMES | {FRAME_MISSION}
#: the commands a rally or fence upload may carry; any other is refused UNSUPPORTED, as
#: both firmwares do (ArduPilot MissionItemProtocol_Rally / _Fence, PX4 mavlink_mission.cpp)
TYPED_COMMANDS = {mavlink.MAV_MISSION_TYPE_RALLY: frozenset({5100}),
                  mavlink.MAV_MISSION_TYPE_FENCE: frozenset({5000, 5001, 5002, 5003, 5004})}
RETRY_S = 1.5
RETRIES = 5


@dataclass(frozen=True)
class MissionItem:
    seq: int
    frame: int
    command: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0                 # degrees * 1e7 in global frames, else the integer param5
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1

    @property
    def is_nav(self) -> bool:
        return self.command < mavlink.MAV_CMD_NAV_LAST

    @property
    def param5(self) -> float:
        """x as a command reads it: a latitude for a navigation command in a global
        frame, else the plain value (a DO command kept in frame 0 by ArduPilot)."""
        return self.x * 1e-7 if self.frame in GLOBAL_FRAMES and self.is_nav else float(self.x)

    @property
    def lat(self) -> float:
        return self.x * 1e-7

    @property
    def lon(self) -> float:
        return self.y * 1e-7

    @classmethod
    def from_msg(cls, msg) -> "MissionItem":
        x, y = msg.x, msg.y
        if msg.get_type() == "MISSION_ITEM":        # float lat/lon in degrees
            scale = 1e7 if msg.frame in GLOBAL_FRAMES else 1.0
            x, y = int(round(x * scale)), int(round(y * scale))
        return cls(msg.seq, msg.frame, msg.command, msg.param1, msg.param2, msg.param3,
                   msg.param4, x, y, msg.z, msg.autocontinue)

    def encode(self, mav, target: tuple, legacy: bool, current: bool, mission_type: int = 0):
        args = (target[0], target[1], self.seq, self.frame, self.command, int(current),
                self.autocontinue, self.param1, self.param2, self.param3, self.param4)
        if legacy:
            scale = 1e-7 if self.frame in GLOBAL_FRAMES else 1.0
            return mav.mission_item_encode(*args, self.x * scale, self.y * scale, self.z,
                                           mission_type)
        return mav.mission_item_int_encode(*args, self.x, self.y, self.z, mission_type)


class MissionServer:
    """Holds the mission of one vehicle and answers the protocol.

    `send(msg)` transmits, `say(severity, text)` sends a STATUSTEXT, `home()` gives
    (lat, lon, alt) for ArduPilot's item 0, `current()` the current index, and
    `changed(kind)` tells the vehicle that the mission was replaced or cleared.
    """

    def __init__(self, flavour, mav, send, say, home, current, changed, boot_time: float,
                 no_space_s: float = 1.0, capacity: int | None = None):
        self.flavour = flavour
        self.capacity = capacity           # items it holds (home included); None: no limit
        self._mav, self._send, self._say = mav, send, say
        self._home, self._current, self._changed = home, current, changed
        self._boot, self._no_space_s = boot_time, no_space_s
        self.items = [self._home_item()] if flavour.home_item else []
        #: mission type (rally, fence) -> its items, as uploaded
        self.other = {mavlink.MAV_MISSION_TYPE_RALLY: [], mavlink.MAV_MISSION_TYPE_FENCE: []}
        self._up = None            # upload in progress
        self._done = None          # (partner, count, type) of the last finished upload: re-ACKed

    def booted(self, now: float) -> None:
        """The autopilot started now (ArduPilot refuses uploads for a moment)."""
        self._boot = now

    def kept(self, item) -> MissionItem:
        """``item`` as the firmware stores it (its profile's ``read_back``)."""
        wire = {name: getattr(item, name) for name in
                ("seq", "frame", "command", "param1", "param2", "param3", "param4", "x", "y",
                 "z", "autocontinue")}
        back = self.flavour.profile.read_back(wire)
        if back is None:
            return item
        return MissionItem(**{name: back[name] for name in wire})

    # -- dispatch ---------------------------------------------------------------------
    def handle(self, msg, now: float) -> bool:
        kind = msg.get_type()
        partner = (msg.get_srcSystem(), msg.get_srcComponent())
        handler = {
            "MISSION_COUNT": self._on_count,
            "MISSION_ITEM": self._on_item, "MISSION_ITEM_INT": self._on_item,
            "MISSION_REQUEST_LIST": self._on_request_list,
            "MISSION_REQUEST": self._on_request, "MISSION_REQUEST_INT": self._on_request,
            "MISSION_CLEAR_ALL": self._on_clear,
            "MISSION_ACK": lambda *a: None,
        }.get(kind)
        if handler is None:
            return False
        handler(msg, partner, now)
        return True

    def tick(self, now: float) -> None:
        up = self._up
        if up is None or now - up["asked"] < RETRY_S:
            return
        if up["tries"] >= RETRIES:
            self._up = None
            self._ack(up["partner"], mavlink.MAV_MISSION_OPERATION_CANCELLED, up["type"])
            return
        up["tries"] += 1
        self._request(now)

    # -- upload -----------------------------------------------------------------------
    def _on_count(self, msg, partner, now) -> None:
        kind = msg.mission_type
        if kind != mavlink.MAV_MISSION_TYPE_MISSION:
            if kind not in self.other:
                return self._ack(partner, mavlink.MAV_MISSION_UNSUPPORTED, kind)
            self._done = None
            if msg.count == 0:
                self.other[kind] = []
                return self._ack(partner, mavlink.MAV_MISSION_ACCEPTED, kind)
            self._up = {"partner": partner, "count": msg.count, "next": 0, "tries": 0,
                        "asked": now, "items": [], "type": kind}
            return self._request(now)
        if self.flavour.home_item and now - self._boot < self._no_space_s:
            return self._no_space(partner, 0)
        if self.capacity is not None and msg.count > self.capacity:
            return self._no_space(partner, self.capacity)
        self._done = None
        if msg.count == 0:
            self._up = None
            self._replace([], "cleared")
            return self._ack(partner, mavlink.MAV_MISSION_ACCEPTED)
        self._up = {"partner": partner, "count": msg.count, "next": 0, "tries": 0,
                    "asked": now, "items": [], "type": kind}
        self._request(now)

    def _no_space(self, partner, capacity: int) -> None:
        """NO_SPACE at MISSION_COUNT, then what the firmware says (ArduPilot: "Only N
        items are supported"; PX4 says nothing)."""
        self._ack(partner, mavlink.MAV_MISSION_NO_SPACE)
        if self.flavour.texts.no_space:
            self._say(mavlink.MAV_SEVERITY_WARNING,
                      self.flavour.texts.no_space.format(n=capacity))

    def _on_item(self, msg, partner, now) -> None:
        up = self._up
        if up is None:
            if self._done == (partner, msg.seq + 1, msg.mission_type):  # our ACK was lost
                self._ack(partner, mavlink.MAV_MISSION_ACCEPTED, msg.mission_type)
            return
        if msg.mission_type != up["type"]:
            return
        if up["type"] != mavlink.MAV_MISSION_TYPE_MISSION:
            return self._on_other_item(msg, partner, now)
        if partner != up["partner"]:
            return self._ack(partner, mavlink.MAV_MISSION_DENIED)
        if msg.seq != up["next"]:                       # out of order: said, and asked again
            if self.flavour.nacks_out_of_order:
                self._ack(partner, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            # at once, where ArduPilot asks again on its own timer: the suite's lossy
            # links at 100x would otherwise spend the simulator's retries
            return self._request(now)
        if msg.frame not in SUPPORTED_FRAMES:
            self._up = None
            return self._ack(partner, mavlink.MAV_MISSION_UNSUPPORTED_FRAME)
        item = self.kept(MissionItem.from_msg(msg))
        up["items"].append(item)
        if self.flavour.home_item:                      # written into the live mission now
            self._write_live(item)
        up["next"] += 1
        up["tries"] = 0
        if up["next"] < up["count"]:
            return self._request(now)
        self._up = None
        self._done = (partner, up["count"], up["type"])
        self._replace(up["items"], "uploaded")
        self._ack(partner, mavlink.MAV_MISSION_ACCEPTED)
        if self.flavour.home_item:
            self._say(mavlink.MAV_SEVERITY_INFO, "Flight plan received")

    def _on_other_item(self, msg, partner, now) -> None:
        """An item of a rally or fence upload: kept as sent, the list replaced whole
        when the last one arrives."""
        up, kind = self._up, self._up["type"]
        if partner != up["partner"]:
            return self._ack(partner, mavlink.MAV_MISSION_DENIED, kind)
        if msg.seq != up["next"]:
            return self._request(now)
        if msg.frame not in SUPPORTED_FRAMES:
            self._up = None
            return self._ack(partner, mavlink.MAV_MISSION_UNSUPPORTED_FRAME, kind)
        if msg.command not in TYPED_COMMANDS[kind]:
            self._up = None
            return self._ack(partner, mavlink.MAV_MISSION_UNSUPPORTED, kind)
        up["items"].append(MissionItem.from_msg(msg))
        up["next"] += 1
        up["tries"] = 0
        if up["next"] < up["count"]:
            return self._request(now)
        self._up = None
        self._done = (partner, up["count"], kind)
        self.other[kind] = up["items"]
        self._ack(partner, mavlink.MAV_MISSION_ACCEPTED, kind)

    def rally(self) -> list:
        """The rally points held: [(lat, lon, alt, frame)]."""
        return [(it.lat, it.lon, float(it.z), it.frame)
                for it in self.other[mavlink.MAV_MISSION_TYPE_RALLY]]

    def _write_live(self, item) -> None:
        if item.seq == 0:
            return                                      # home stays the real home
        while len(self.items) <= item.seq:
            self.items.append(None)
        self.items[item.seq] = item

    def _replace(self, items, kind) -> None:
        items = list(items)
        if self.flavour.home_item:
            items = [self._home_item()] + items[1:]
        self.items = items
        self._changed(kind)

    def _request(self, now) -> None:
        up = self._up
        up["asked"] = now
        target = up["partner"]
        if self.flavour.legacy_request:
            self._send(self._mav.mission_request_encode(*target, up["next"], up["type"]))
        else:
            self._send(self._mav.mission_request_int_encode(*target, up["next"], up["type"]))

    # -- download and clear -----------------------------------------------------------
    def _on_request_list(self, msg, partner, now) -> None:
        kind = msg.mission_type
        count = len(self.items) if kind == mavlink.MAV_MISSION_TYPE_MISSION \
            else len(self.other.get(kind, []))
        self._send(self._mav.mission_count_encode(*partner, count, kind))

    def _on_request(self, msg, partner, now) -> None:
        kind = msg.mission_type
        if kind != mavlink.MAV_MISSION_TYPE_MISSION:
            held = self.other.get(kind, [])
            if not 0 <= msg.seq < len(held):
                return self._ack(partner, mavlink.MAV_MISSION_INVALID_SEQUENCE, kind)
            legacy = msg.get_type() == "MISSION_REQUEST"
            return self._send(held[msg.seq].encode(self._mav, partner, legacy, False, kind))
        if not 0 <= msg.seq < len(self.items) or self.items[msg.seq] is None:
            return self._ack(partner, mavlink.MAV_MISSION_INVALID_SEQUENCE)
        item = self._home_item() if (self.flavour.home_item and msg.seq == 0) \
            else self.items[msg.seq]
        legacy = msg.get_type() == "MISSION_REQUEST"
        self._send(item.encode(self._mav, partner, legacy, msg.seq == self._current()))

    def _on_clear(self, msg, partner, now) -> None:
        if msg.mission_type == mavlink.MAV_MISSION_TYPE_MISSION:
            self._up = None
            self._replace([], "cleared")
        elif msg.mission_type in self.other:
            self.other[msg.mission_type] = []
        self._ack(partner, mavlink.MAV_MISSION_ACCEPTED, msg.mission_type)

    def _ack(self, partner, result, mission_type=mavlink.MAV_MISSION_TYPE_MISSION) -> None:
        self._send(self._mav.mission_ack_encode(*partner, result, mission_type))

    def _home_item(self) -> MissionItem:
        lat, lon, alt = self._home()
        return MissionItem(0, mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_WAYPOINT,
                           x=int(round(lat * 1e7)), y=int(round(lon * 1e7)), z=float(alt))

    def item(self, seq: int):
        """The live item at `seq` (None past the end or not yet written)."""
        if 0 <= seq < len(self.items):
            it = self.items[seq]
            return replace(it, seq=seq) if it is not None else None
        return None
