"""Before anything is armed: where the vehicles stand, what their autopilots would
do on their own, and how fast they are set to fly.

- `locate`: every vehicle at its route's launch point, within the plan's track
  tolerance (a vehicle elsewhere would climb and fly a first leg nobody proved
  hidden): refused by name, or with ``from_where_they_stand`` the fleet planned
  again from where they stand (`planner.replan.plan_from_bases`);
- `check_failsafes`: every failsafe of every autopilot stays within the proof
  (`gcs.flight.failsafes`), or the flight is refused;
- `check_rates`: where an autopilot's own rate limits are below the plan's, said.
"""

from autopilots import firmware_of
from common.geo import distance_m
from gcs import commands
from gcs import params as gcs_params
from gcs.monitor import LOST
from planner.fleet import stop_time

from . import failsafes
from .options import FlightError, launch_tolerance

#: m/s an autopilot's rate limit may fall short of the plan's (float32, unit rounding)
RATE_SLACK_MPS = 0.01


def start_of(route):
    """Where a route's vehicle must stand to start it: its launch point, or under its
    first waypoint when the plan has none (None for a route without waypoints)."""
    if route.launch is not None:
        return route.launch
    return route.waypoints[0] if route.waypoints else None


def start_name(route) -> str:
    return "the launch point" if route.launch is not None else "under the first waypoint"


class FailsafeRefused(FlightError):
    """A vehicle's failsafe would fly out of the proof: refused before arming (exit 2)."""


class Preflight:
    """The checks of one flight before arming (see the module doc). ``replan(off)``:
    plans the fleet again from where the ``off`` vehicles stand and flies that plan
    instead (`gcs.flight.Flight.plan_from_where_they_stand`)."""

    def __init__(self, state, replan):
        self.state, self.replan = state, replan
        #: sysid -> {"read": settings, "set": changes, "risks": lines} (flight.json)
        self.failsafes = {}

    def locate(self) -> None:
        """Wait for every vehicle's position (ArduPilot reports none before its EKF
        has an origin), then `check_positions`: before anything is uploaded or armed."""
        m = self.state.monitor
        self.state.on_every(lambda sysid: commands.wait_position(
            m.links[sysid], self.state.options.ready_timeout_s), "locating", commands.CommandError)
        self.check_positions()

    def check_positions(self) -> None:
        """Before anything is armed: every vehicle stands at its route's launch point
        (its reported position), within the plan's track tolerance, the room its
        takeoff column is proven with. A vehicle elsewhere would climb and fly a
        first leg nobody proved hidden: FlightError naming each one and how far off it
        stands, or with ``from_where_they_stand`` the fleet planned again from where
        they stand. (Its home is not compared: ArduPilot and PX4 both set home where
        they arm.)"""
        off = self.off_launch()
        if off and self.state.options.from_where_they_stand:
            self.replan(off)
            off = self.off_launch()          # the new plan's bases: where they stand
        if off:
            lines = [f"vehicle {sysid} stands {d:.1f} m from {start_name(route)} of route "
                     f"{route.id} ({lat:.7f},{lon:.7f}, not {start_of(route).lat:.7f},"
                     f"{start_of(route).lon:.7f})" for sysid, route, d, lat, lon in off]
            for line in lines:
                self.state.monitor.event(None, f"refused: {line}")
            raise FlightError("; ".join(lines) + f": each must stand within "
                              f"{launch_tolerance(self.state.plan):g} m of where its route "
                              "starts (the plan's track tolerance) before it is armed")

    def off_launch(self) -> list:
        """[(sysid, route, metres, lat, lon)] of the vehicles standing farther from their
        route's launch point (or, for a plan without one, from under its first
        waypoint: it climbs straight up to it) than the launch tolerance."""
        tolerance = launch_tolerance(self.state.plan)
        m = self.state.monitor
        off = []
        for sysid, v in sorted(m.vehicles.items()):
            launch, s = start_of(v.route), m.links[sysid].state
            if launch is None or v.state == LOST or s.lat is None:
                continue
            d = distance_m(launch.lat, launch.lon, s.lat, s.lon)
            if d > tolerance:
                off.append((sysid, v.route, d, s.lat, s.lon))
        return off

    def check_failsafes(self) -> None:
        """Every failsafe of every vehicle, read before arming (`gcs.flight.failsafes`):
        what its autopilot would fly when one fires must stay within the proof. One
        that would not refuses the flight (`FailsafeRefused`, naming each parameter,
        what it would do and the fix), unless the options say ``set_failsafes``: then
        the hidden-safe values are written and read back, and the previous ones kept
        (`set`, in flight.json). What stays a known risk is said per vehicle."""
        m, refused = self.state.monitor, {}
        for sysid, v in sorted(m.vehicles.items()):
            link = m.links[sysid]
            profile = commands.autopilot(link)
            if not profile.failsafes or v.state == LOST:
                continue
            settings = failsafes.read(link, profile)
            self.failsafes[sysid] = {"read": [s.report() for s in settings]}
            if any(s.to_set for s in settings) and self.state.options.set_failsafes:
                settings = self._make_hidden(sysid, link, profile)
            if failsafes.unproven(settings):
                refused[sysid] = failsafes.refusal(settings)
                m.event(sysid, "refused: " + refused[sysid])
            else:
                m.event(sysid, "failsafes hidden: " + "; ".join(s.said() for s in settings))
            said = failsafes.risks(profile, settings) + \
                failsafes.buffer_risks(link, profile, self._planned_route(v))
            self.failsafes[sysid]["risks"] = said
            if said:
                m.event(sysid, "known risk: " + "; ".join(said))
        if refused:
            raise FailsafeRefused(failsafes.by_vehicles(refused) + ": " + failsafes.FIX)

    def _planned_route(self, v):
        """The plan's whole route of a vehicle, every sortie (the monitor's is the one
        it flies now)."""
        return next((r for r in self.state.plan.vehicles if r.id == v.vehicle_id), v.route)

    def _make_hidden(self, sysid, link, profile) -> list:
        """--set-failsafes: the hidden-safe values written and read back; the settings
        as they are now (FlightError when one does not read back)."""
        try:
            changes = failsafes.make_hidden(link, failsafes.read(link, profile))
        except failsafes.FailsafeError as exc:
            self.failsafes[sysid]["set"] = exc.changes
            raise FlightError(f"{exc}: the flight is not started (`gcs failsafes "
                              "--restore` puts back what was set)") from None
        self.failsafes[sysid]["set"] = changes
        self.state.monitor.event(sysid, "failsafes set: " + ", ".join(
            f"{c['parameter']} {c['previous']:g} -> {c['value']:g}" for c in changes))
        return failsafes.read(link, profile)

    def check_rates(self) -> None:
        """Say, one line per vehicle, where its autopilot's own limits on a mission's
        speed, climb or descent (the profile's `rate_limits`: ArduPilot
        WPNAV_SPEED_UP / _DN, PX4 MPC_XY_VEL_MAX, MPC_Z_V_AUTO_UP / _DN) are below the
        plan's: the legs they cap take longer than planned, and the fleet's
        schedule, its separation and each sortie's battery were planned on the
        plan's figures."""
        m, params = self.state.monitor, self.state.params
        for sysid, v in sorted(m.vehicles.items()):
            link = m.links[sysid]
            if v.state == LOST:
                continue
            slower = []
            limits = commands.autopilot(link).rate_limits
            values = gcs_params.read_many(link, [name for name, _, _ in limits], retries=1)
            for name, rate, unit in limits:
                planned, value = params.get(rate), values[name] and values[name].value
                if planned is not None and value is not None and \
                        value * unit < float(planned) - RATE_SLACK_MPS:
                    slower.append(f"{name} = {value:g} ({value * unit:g} m/s, the plan's "
                                  f"{rate} {float(planned):g})")
            stops = self._stop_said(commands.autopilot(link).name)
            if stops:
                slower.append(stops)
            if slower:
                m.event(sysid, "slower than planned: " + "; ".join(slower) + ": its legs take "
                        "longer than the plan's times, on which its schedule, separation and "
                        "battery were planned; set the parameters to the plan's rates, or "
                        "plan with the vehicle's")

    def _stop_said(self, firmware):
        """What a vehicle of ``firmware`` loses at a waypoint beyond what the plan
        counts, said; None when no more (a PX4 vehicle flying a plan made for
        ArduPilot stops at each: 2.7 s more a waypoint at 12 m/s)."""
        params = self.state.params
        planned = stop_time(params)
        own = stop_time(dict(params, firmware=firmware))
        if own <= planned + 1e-6:
            return None
        return (f"each waypoint {own:.1f} s ({firmware} stops at each) where the plan counts "
                f"{planned:.1f} s (planned for {firmware_of(params)})")
