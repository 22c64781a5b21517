"""The simulated ground-station link-loss failsafe, as each firmware flies it.

A vehicle that has heard the ground station's HEARTBEAT and then hears nothing for
the firmware's timeout takes its link-loss action, once per loss:

- ArduCopter (ArduCopter/events.cpp failsafe_gcs_check / failsafe_gcs_on_event):
  FS_GCS_ENABLE picks the action after FS_GCS_TIMEOUT s (5 by default); bit 1 of
  FS_OPTIONS flies a mission in AUTO on. Disarmed, nothing happens.
- PX4 (commander, failsafe/failsafe.cpp): NAV_DLL_ACT after COM_DL_LOSS_T s (10 by
  default); bit 0 of COM_DLL_EXCEPT flies a mission on.

Each action is a mode, "A or B" (B where A is refused: SmartRTL without its path),
"fall" (motors off) or None (nothing), as the battery failsafes' are
(`gcs.sim.battery`).
"""

from dataclasses import dataclass

#: FS_GCS_ENABLE: 2 was 'continue in AUTO' before 4.0 and is RTL now; 6 is the
#: mission's DO_LAND_START, RTL without one; 7 brakes, then lands
ARDUPILOT_ACTIONS = {0: None, 1: "RTL", 2: "RTL", 3: "SMART_RTL or RTL",
                     4: "SMART_RTL or LAND", 5: "LAND", 6: "RTL", 7: "LAND"}
#: NAV_DLL_ACT: 1 holds where it is, 2 returns (RTL_TYPE says how), 3 lands there
PX4_ACTIONS = {0: None, 1: "AUTO.LOITER", 2: "AUTO.RTL", 3: "AUTO.LAND", 5: "fall",
               6: "fall"}


@dataclass(frozen=True)
class LinkLoss:
    """What a vehicle does ``timeout_s`` of its time after it last heard the ground
    station: ``action``, unless it flies a mission in ``continue_in`` mode."""
    timeout_s: float
    action: str | None
    continue_in: str | None       # the mission's mode, where the firmware flies it on


def ardupilot_link_loss(params: dict) -> LinkLoss:
    on_in_auto = int(params.get("FS_OPTIONS", 0)) & 0b10
    return LinkLoss(float(params.get("FS_GCS_TIMEOUT", 5.0)),
                    ARDUPILOT_ACTIONS.get(int(params.get("FS_GCS_ENABLE", 0))),
                    "AUTO" if on_in_auto else None)


def px4_link_loss(params: dict) -> LinkLoss:
    on_in_mission = int(params.get("COM_DLL_EXCEPT", 0)) & 0b1
    return LinkLoss(float(params.get("COM_DL_LOSS_T", 10.0)),
                    PX4_ACTIONS.get(int(params.get("NAV_DLL_ACT", 0))),
                    "AUTO.MISSION" if on_in_mission else None)
