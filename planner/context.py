"""The planning context: everything a plan was made in, in memory and in its folder.

`planner.pipeline.prepare` makes a `PlanningContext` (terrain, outposts,
exposure surface, viewpoints, visibility sets, travel graph, travel times);
re-planning in flight, exports and mission checks use it again. ``save``
writes what cannot be cheaply recomputed into the plan folder, in files a user
can open too, and ``load`` reads it back without redoing the heavy stages:

| file | contents |
|---|---|
| ``plan.json`` | the scenario (``params``) and the outposts (with their ground) |
| ``terrain.tif`` | the working grid: line-of-sight and clearance surfaces (float64) |
| ``lowest_seen.tif`` | lowest altitude any outpost sees, per cell (float64; inf: none) |
| ``viewpoints.csv`` | candidate viewpoints: id, lon, lat, alt_amsl, row, col, region |
| ``visibility.npz`` | visibility sets (CSR rows per viewpoint, target cells) |
| ``travel.npz`` | the hidden travel graph's checked edges (node cells, dip altitudes) |

The viewpoint-to-viewpoint times are recomputed from the graph on first use
(`PlanningContext.travel`), a few seconds, on a background thread in `gcs fly`.
A folder without these files (copied without them, or written by an older
version) is refused here (`MissingContext`, naming the file);
`planner.pipeline.load_context` runs its stages again instead.
"""

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from common.errors import InputError
from common.fileio import save_npz
from planner.exposure import (
    ExposureParams,
    ExposureSurface,
    Outpost,
    lowest_seen,
    restricted,
    surface_from_lowest,
)
from planner.plan import PLAN_FILE, TERRAIN_FILE, Plan
from planner.scenario import Scenario
from planner.split import n_parts
from planner.terrain import Terrain, read_grid, read_terrain, write_grid
from planner.terrain.area import areas
from planner.travel import TravelGraph, TravelParams
from planner.visibility import Viewpoints, VisibilityMatrix
from planner.visibility.unseen import OUTSIDE, REASONS

LOWEST_SEEN_FILE = "lowest_seen.tif"
UNSEEN_FILE = "unseen.tif"
UNSEEN_LEGEND = ("0 target, " + ", ".join(f"{code} {why}" for code, why in REASONS.items())
                 + f", {OUTSIDE} outside the area of operations")
VIEWPOINTS_FILE = "viewpoints.csv"
VISIBILITY_FILE = "visibility.npz"
TRAVEL_FILE = "travel.npz"


@dataclass
class PlanningContext:
    scenario: Scenario
    terrain: Terrain
    outposts: list  # [Outpost]
    surface: ExposureSurface
    regions: tuple  # flyable region ids the fleet uses
    viewpoints: Viewpoints
    visibility: VisibilityMatrix
    graph: TravelGraph
    times: Optional[np.ndarray] = None  # [n_vp, n_vp] hidden times, s; see `travel`
    timing_s: dict = field(default_factory=dict)
    overlay: Optional[tuple] = None  # see `viewpoint_overlay`
    unseen: Optional[np.ndarray] = None  # uint8 grid, `planner.visibility.unseen_reasons`

    @property
    def travel(self) -> np.ndarray:
        """[n_vp, n_vp] hidden travel times between viewpoints (s), computed once."""
        if self.times is None:
            self.times = self.graph.time_matrix(self.viewpoints.xyz)
        return self.times

    def viewpoint_overlay(self, client=None, progress=None) -> tuple:
        """The sparse overlay of the viewpoints (`TravelGraph.overlay`), which the
        parts' travel times of plans in parts come from: made once and kept (a few
        MB even on 4096²; re-plans in flight reuse it)."""
        if self.overlay is None:
            self.overlay = self.graph.overlay(self.viewpoints.xyz, client=client,
                                              progress=progress)
        return self.overlay

    @property
    def in_parts(self) -> bool:
        """Plans here are made in parts (`planner.split`), each with its own travel
        times: `travel` over all the viewpoints is never needed (nor affordable)."""
        return n_parts(len(self.viewpoints), self.scenario) > 1

    @property
    def travel_params(self) -> TravelParams:
        return self.scenario.travel_params()

    # --- the plan folder ----------------------------------------------------------------
    def save(self, directory) -> list:
        """Write the context's files into ``directory`` (beside plan.json and
        terrain.tif, which the plan writes); returns [(path, what)]."""
        d = Path(directory)
        write_grid(d / LOWEST_SEEN_FILE, self.surface.lowest_seen, self.terrain,
                   descriptions=("lowest altitude an outpost sees, m AMSL (inf: none)",))
        _write_viewpoints(d / VIEWPOINTS_FILE, self.terrain, self.viewpoints)
        written = []
        if self.unseen is not None:
            write_grid(d / UNSEEN_FILE, self.unseen, self.terrain, nodata=OUTSIDE,
                       descriptions=(UNSEEN_LEGEND,))
            written.append((d / UNSEEN_FILE, f"why ground is not a target: {UNSEEN_LEGEND}"))
        v = self.visibility
        save_npz(d / VISIBILITY_FILE, indptr=v.indptr, indices=v.indices,
                 target_indptr=v.target_indptr, target_viewpoints=v.target_viewpoints,
                 target_cells=v.target_cells, grid_shape=np.array(v.grid_shape))
        save_npz(d / TRAVEL_FILE, **self.graph.edges(compact=True),
                 regions=np.array(self.regions))
        return written + [(d / LOWEST_SEEN_FILE, "lowest altitude any outpost sees, float64"),
                (d / VIEWPOINTS_FILE, "candidate viewpoints (for re-planning)"),
                (d / VISIBILITY_FILE, "visibility sets of the viewpoints (numpy npz)"),
                (d / TRAVEL_FILE, "hidden travel graph (numpy npz)")]

    @classmethod
    def load(cls, directory, plan: Optional[Plan] = None) -> "PlanningContext":
        """The context a saved plan was made in, from its folder."""
        d = Path(directory)
        plan = plan or Plan.load(d)
        surface = load_surface(d, plan)
        scenario = Scenario.from_params(plan.params, source=d / PLAN_FILE)
        flight = areas(surface.terrain, scenario.area, scenario.area_file,
                       scenario.area_flight)[1]
        if flight is not None:  # re-planned routes stay inside the area too
            surface = restricted(surface, flight)
        for name in (VIEWPOINTS_FILE, VISIBILITY_FILE, TRAVEL_FILE):
            if not (d / name).is_file():
                raise MissingContext(d / name, scenario, surface)
        with np.load(d / TRAVEL_FILE) as saved:
            graph = TravelGraph(surface, scenario.travel_params(),
                                edges={k: saved[k] for k in saved.files if k != "regions"})
            regions = tuple(int(r) for r in saved["regions"])
        with np.load(d / VISIBILITY_FILE) as saved:
            visibility = VisibilityMatrix(saved["indptr"], saved["indices"],
                                          saved["target_indptr"], saved["target_viewpoints"],
                                          saved["target_cells"], tuple(saved["grid_shape"]))
        viewpoints = _read_viewpoints(d / VIEWPOINTS_FILE, surface)
        unseen = None
        if (d / UNSEEN_FILE).is_file():
            unseen = read_grid(d / UNSEEN_FILE, surface.terrain.shape)
        return cls(scenario, surface.terrain, surface.outposts, surface, regions, viewpoints,
                   visibility, graph, unseen=unseen)


class MissingContext(InputError):
    """A plan folder without a file of its context: what was read of it (its
    scenario, its surface cut to the area) comes with it, for the stages to be run
    again (`planner.pipeline.load_context`)."""

    def __init__(self, path, scenario, surface):
        super().__init__(path, "missing from the plan folder (it keeps what the plan was "
                               "made in): plan it again")
        self.scenario, self.surface = scenario, surface


def load_surface(directory, plan: Plan) -> ExposureSurface:
    """The exposure surface a saved plan was made against: its terrain, outposts
    and lowest seen altitudes, as planned (no sweep is run again; a folder
    without lowest_seen.tif, from an older version, gets it computed)."""
    d = Path(directory)
    terrain = read_terrain(d / TERRAIN_FILE)
    outposts = plan_outposts(terrain, plan)
    p = plan.params
    params = ExposureParams(ceiling_agl_m=p["ceiling_agl_m"], clearance_m=p["clearance_m"],
                            hide_margin_m=p["hide_margin_m"],
                            curvature_coeff=p["curvature_coeff"])
    if (d / LOWEST_SEEN_FILE).is_file():
        lowest = read_terrain(d / LOWEST_SEEN_FILE).height
        if lowest.shape != terrain.shape:
            raise InputError(d / LOWEST_SEEN_FILE, "not on the grid of terrain.tif")
    else:
        lowest = lowest_seen(terrain, outposts, params)
    return surface_from_lowest(terrain, outposts, params, lowest)


def plan_outposts(terrain, plan: Plan) -> list:
    """The plan's outposts on the working grid (their ground as planned)."""
    lon = np.array([o["lon"] for o in plan.outposts], float)
    lat = np.array([o["lat"] for o in plan.outposts], float)
    x, y = terrain.from_lonlat(lon, lat) if len(lon) else ([], [])
    return [Outpost(float(xi), float(yi), float(o["height_m"]),
                    float("inf") if o.get("range_m") is None else float(o["range_m"]),
                    float(o["lon"]), float(o["lat"]), o.get("name", ""),
                    float("nan") if o.get("ground_amsl") is None else float(o["ground_amsl"]))
            for xi, yi, o in zip(x, y, plan.outposts)]


def outposts_json(outposts) -> list:
    """The outposts as plan.json keeps them (`plan_outposts` reads them back)."""
    return [{"lon": o.lon, "lat": o.lat, "height_m": o.height_m,
             "range_m": o.range_m if np.isfinite(o.range_m) else None, "name": o.name,
             "ground_amsl": o.ground_m} for o in outposts]


_VIEWPOINT_COLUMNS = ("id", "lon", "lat", "alt_amsl", "row", "col", "region")


def _write_viewpoints(path, terrain, viewpoints) -> None:
    lon, lat = terrain.to_lonlat(viewpoints.xyz[:, 0], viewpoints.xyz[:, 1])
    with open(path, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f)
        out.writerow(_VIEWPOINT_COLUMNS)
        for i in range(len(viewpoints)):
            r, c = viewpoints.indices[i]
            out.writerow([i, f"{lon[i]:.9f}", f"{lat[i]:.9f}", repr(float(viewpoints.xyz[i, 2])),
                          int(r), int(c), int(viewpoints.region[i])])


def _read_viewpoints(path, surface) -> Viewpoints:
    """Viewpoints at their cells' centres and saved altitudes (exact: the cells' own
    centres, not the rounded lon/lat, place them)."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        cells = np.array([[int(r["row"]), int(r["col"])] for r in rows], np.int64).reshape(-1, 2)
        z = np.array([float(r["alt_amsl"]) for r in rows])
        region = np.array([int(r["region"]) for r in rows], np.int32)
    except (KeyError, ValueError) as exc:
        raise InputError(path, f"malformed viewpoints file ({exc})") from None
    x, y = surface.terrain.xy(cells[:, 0], cells[:, 1])
    return Viewpoints(cells, np.stack([x, y, z], axis=1).reshape(-1, 3), region)
