"""The true track of a simulated vehicle, written where tests can judge the flight.

File ``vehicle_<sysid>.json`` in the track directory, rewritten atomically every
couple of wall seconds and when the vehicle stops or is killed::

    {"format": "gcs-sim-track/3", "sysid": 1, "firmware": "ardupilot",
     "home": [lat, lon, alt_amsl],
     "columns": ["t", "lat", "lon", "alt", "wall", "used"],
     "samples": [[t, lat, lon, alt, wall, used], ...],   # mission time s since boot,
                                   # degrees, m AMSL, the wall clock (Unix s), the share
                                   # of a full battery drawn from the pack in it
     "snapshots": [{"t", "lat", "lon", "alt", "seq"}],   # seq: mission item, or null for a command
     "events": [{"t", "event"}],      # boot, armed, takeoff, reached N, landed, killed: ...
     "killed_at": t or null, "complete": bool,     # complete: the file was closed on purpose
     "real_time_s": s}          # wall s flown at 1x while the ground station was busy

Samples are taken every 0.1 s of mission time (10 Hz; never more than 0.15 s
apart) and at boot, touchdown and kill. Each vehicle's mission time is its own
(counted from its boot; a fleet's clocks stay within a few ticks of each other,
`gcs.sim.lockstep`), so tracks of a fleet are compared on the wall clock, the
one they share (``wall``). While the ground
station in the same process computes (`gcs.busy`: a re-plan, an upload) the
simulator runs at real time, and says for how long (``real_time_s``).
"""

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.fileio import write_text_atomic

FORMAT = "gcs-sim-track/3"
SAMPLE_PERIOD_S = 0.1


def track_path(track_dir, sysid: int) -> Path:
    return Path(track_dir) / f"vehicle_{sysid}.json"


class TrackRecorder:
    def __init__(self, path, sysid: int, firmware: str, home: tuple):
        self.path = Path(path) if path is not None else None
        self._head = {"format": FORMAT, "sysid": sysid, "firmware": firmware,
                      "home": list(home),
                      "columns": ["t", "lat", "lon", "alt", "wall", "used"]}
        self.samples, self.snapshots, self.events = [], [], []
        self.killed_at = None
        self.real_time_s = 0.0    # wall s run at 1x while the ground station was busy
        self._next_sample = 0.0
        self._dirty = True
        self._encoded = []        # the samples written so far, as JSON text in pieces
        self._n_encoded = 0

    def sample(self, t: float, lat: float, lon: float, alt: float, used: float,
               force=False) -> None:
        if t + 1e-9 < self._next_sample and not force:
            return
        while self._next_sample <= t + 1e-9:      # stay on the grid: no drift, no gaps
            self._next_sample += SAMPLE_PERIOD_S
        self.samples.append([round(t, 3), round(lat, 9), round(lon, 9), round(alt, 3),
                             round(time.time(), 4), round(used, 6)])
        self._dirty = True

    def snapshot(self, t, lat, lon, alt, seq=None) -> None:
        self.snapshots.append({"t": round(t, 3), "lat": round(lat, 9), "lon": round(lon, 9),
                               "alt": round(alt, 3), "seq": seq})
        self._dirty = True

    def event(self, t: float, text: str) -> None:
        self.events.append({"t": round(t, 3), "event": text})
        self._dirty = True

    def flush(self, complete=False) -> None:
        if self.path is None or not (self._dirty or complete):
            return
        doc = dict(self._head, samples=[], snapshots=self.snapshots,
                   events=self.events, killed_at=self.killed_at, complete=complete,
                   real_time_s=round(self.real_time_s, 3))
        text = json.dumps(doc, separators=(",", ":"))
        # the samples encoded once each: a flight's file is rewritten every couple of
        # wall seconds, and encoding all of it each time was a fifth of a simulated
        # flight's work
        if len(self.samples) > self._n_encoded:
            self._encoded.append(json.dumps(self.samples[self._n_encoded:],
                                            separators=(",", ":"))[1:-1])
            self._n_encoded = len(self.samples)
        samples = '"samples":[' + ",".join(self._encoded) + "]"
        write_text_atomic(self.path, text.replace('"samples":[]', samples, 1))
        self._dirty = False


@dataclass
class Track:
    sysid: int
    firmware: str
    home: tuple
    t: np.ndarray          # s of mission time
    lat: np.ndarray
    lon: np.ndarray
    alt: np.ndarray        # m AMSL
    wall: np.ndarray       # Unix s: the clock a fleet's tracks share
    used: np.ndarray       # share of a full battery drawn from the pack in it
    snapshots: list
    events: list
    killed_at: float | None
    complete: bool


def read_track(path) -> Track:
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    if doc.get("format") != FORMAT:
        raise ValueError(f"{path}: not a {FORMAT} track file")
    rows = np.asarray(doc["samples"], dtype=float).reshape(-1, len(doc["columns"]))
    return Track(doc["sysid"], doc["firmware"], tuple(doc["home"]), *rows[:, :6].T,
                 doc["snapshots"], doc["events"], doc["killed_at"], doc["complete"])
