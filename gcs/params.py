"""Parameters read and written as each firmware encodes them (PARAM_REQUEST_READ,
PARAM_SET, PARAM_VALUE).

ArduPilot sends every value as a float, an integer parameter cast to it ("C-cast"
encoding); PX4 sends an INT32 parameter's four bytes in the float field
(MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE, src/modules/mavlink/mavlink_main.cpp)
and takes a PARAM_SET only in the parameter's own type (a mismatch is refused
without an answer: mavlink_parameters.cpp). A value is read with its type, and
written back in it.
"""

import struct
import time
from dataclasses import dataclass

from gcs.mavlink import M

#: wall s to wait for an answer before asking again, and how many times again: a
#: preflight reads a dozen failsafe parameters per vehicle, and at 20 % loss each
#: way one exchange in three fails (three tries refused the flight in 3 of 3 runs
#: of the lossy end-to-end test: a read unanswered, or a set not read back); ten
#: tries of 0.75 s miss about one in 27,000 and give up on a parameter the firmware
#: lacks after 7.5 s
TIMEOUT_S = 0.75
RETRIES = 9
#: the MAV_PARAM_TYPEs that hold integers
INTEGER_TYPES = frozenset({M.MAV_PARAM_TYPE_UINT8, M.MAV_PARAM_TYPE_INT8,
                           M.MAV_PARAM_TYPE_UINT16, M.MAV_PARAM_TYPE_INT16,
                           M.MAV_PARAM_TYPE_UINT32, M.MAV_PARAM_TYPE_INT32})


@dataclass(frozen=True)
class Value:
    value: float
    kind: int                       # MAV_PARAM_TYPE as the vehicle reported it


def decode(wire: float, kind: int, bytewise: bool) -> float:
    """A PARAM_VALUE's value: an integer's bytes where the firmware sends them so."""
    if bytewise and kind in INTEGER_TYPES:
        return float(struct.unpack("<i", struct.pack("<f", wire))[0])
    return float(wire)


def encode(value: float, kind: int, bytewise: bool) -> float:
    """The float field of a PARAM_SET of ``value`` in type ``kind``."""
    if bytewise and kind in INTEGER_TYPES:
        return struct.unpack("<f", struct.pack("<i", int(value)))[0]
    return float(value)


def _bytewise(link) -> bool:
    profile = getattr(link, "profile", None)
    return bool(getattr(profile, "params_bytewise", False))


def _drain(link, name: str) -> None:
    """Drop the PARAM_VALUEs of ``name`` already queued: PX4 answers a PARAM_SET and
    also announces the change, so a later read would otherwise take a stale one."""
    while link.recv("PARAM_VALUE", 0.0, lambda m: m.param_id == name) is not None:
        pass


def read(link, name: str, timeout_s: float = TIMEOUT_S, retries: int = RETRIES):
    """`Value` of parameter ``name``; None when the vehicle does not answer (it has
    no such parameter)."""
    return read_many(link, [name], timeout_s, retries)[name]


def read_many(link, names, timeout_s: float = TIMEOUT_S, retries: int = RETRIES) -> dict:
    """{name: `Value` or None} of parameters ``names``, asked together: each round asks
    for every one not yet answered and waits up to ``timeout_s`` for the answers. A
    dozen failsafe parameters read one after the other cost a dozen round trips,
    and on a lossy radio a timeout for each one lost: at 20 % loss each way, 4
    vehicles' preflight took 76 s that way."""
    pending = list(dict.fromkeys(names))
    out = dict.fromkeys(pending)
    for name in pending:
        _drain(link, name)
    for _ in range(retries + 1):
        if not pending:
            break
        for name in pending:
            link.send("PARAM_REQUEST_READ", param_id=name.encode(), param_index=-1)
        deadline = time.monotonic() + timeout_s
        while pending:
            msg = link.recv("PARAM_VALUE", max(0.0, deadline - time.monotonic()),
                            lambda m: m.param_id in pending)
            if msg is None:
                break
            kind = int(msg.param_type)
            out[msg.param_id] = Value(decode(msg.param_value, kind, _bytewise(link)), kind)
            pending.remove(msg.param_id)
    return out


def write(link, name: str, value: float, kind: int, timeout_s: float = TIMEOUT_S,
          retries: int = RETRIES):
    """Set ``name`` to ``value`` in its type ``kind``; the `Value` the vehicle answers
    with (what it now holds), or None when it does not answer."""
    wire = encode(value, kind, _bytewise(link))
    _drain(link, name)
    for _ in range(retries + 1):
        link.send("PARAM_SET", param_id=name.encode(), param_value=wire, param_type=kind)
        msg = link.recv("PARAM_VALUE", timeout_s, lambda m: m.param_id == name)
        if msg is not None:
            kind_back = int(msg.param_type)
            return Value(decode(msg.param_value, kind_back, _bytewise(link)), kind_back)
    return None
