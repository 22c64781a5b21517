"""The flight as the separation guard sees it: `GuardFleet`, what it reads of a
flight and asks of its vehicles."""


class GuardFleet:
    """What the guard reads of a flight and asks of its vehicles (a flight's
    `gcs.flight.holds.Holds`; tests give their own)."""

    def airborne(self) -> list:
        """The system ids flying now."""
        return []

    def hold(self, sysid) -> None:
        """Hold ``sysid`` where it is (its firmware's hold mode)."""

    def resume(self, sysid) -> None:
        """Fly ``sysid`` on along its route."""

    def on_pad(self, sysid) -> bool:
        """Touched down at its base, not yet told landed."""
        return False

    def short(self, sysid) -> bool:
        """Short of battery: it goes before every other."""
        return False

    def waiting(self, sysid):
        """Fleet seconds until a re-plan flies it on, None if it waits for none."""
        return None

    def lands_here(self, sysid) -> bool:
        """It may land from where it is (`land`)."""
        return False

    def land(self, sysid) -> None:
        """Land it from where it is."""
        self.resume(sysid)
