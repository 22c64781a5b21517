"""Hostile outposts (`Outpost`) and their GeoJSON reader."""

from dataclasses import dataclass

DEFAULT_HEIGHT_M = 2.0


@dataclass(frozen=True)
class Outpost:
    """An observer post: a UAV it sees is shot at.

    ``x, y`` are in the terrain grid's projected CRS; ``height_m`` is the eye
    height above ground; ``range_m`` is the detection range (inf = unlimited).
    """

    x: float
    y: float
    height_m: float = DEFAULT_HEIGHT_M
    range_m: float = float("inf")
    lon: float = float("nan")
    lat: float = float("nan")
    name: str = ""
