"""The simulated vehicle's parameters on the wire, as its firmware sends and takes
them (`gcs.params`): an INT32 parameter of a bytewise firmware (PX4) travels as
its bytes and is set only as INT32; everything else as a plain float."""

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs.params import decode, encode


def param_type(flavour, name: str) -> int:
    return mavlink.MAV_PARAM_TYPE_INT32 if name in flavour.int_params \
        else mavlink.MAV_PARAM_TYPE_REAL32


def wire(flavour, name: str, value: float) -> tuple:
    """(PARAM_VALUE's float, its MAV_PARAM_TYPE) for ``name`` at ``value``."""
    kind = param_type(flavour, name)
    return encode(value, kind, flavour.profile.params_bytewise), kind


def value_set(flavour, msg) -> float | None:
    """The value a PARAM_SET sets; None when the firmware refuses it (PX4: a type
    other than the parameter's, src/modules/mavlink/mavlink_parameters.cpp)."""
    kind = param_type(flavour, msg.param_id)
    bytewise = flavour.profile.params_bytewise
    if bytewise and int(msg.param_type) != kind:
        return None
    return decode(msg.param_value, kind, bytewise)
