"""One palette for every picture and file: PNG plots, KML, GeoJSON and the live map.

A vehicle's colour follows its plan vehicle id (UAV 1 is always the first
colour), whatever draws it. Red belongs to the outposts and their ranges, so
no vehicle is red; the base (launch point) is a white square.
"""

#: vehicle colours, by plan vehicle id (1 -> the first); no red, which marks outposts.
#: Sixteen, so that fleets of operational size (12 UAVs on 2048²) repeat none
VEHICLE_COLOURS = ("#1f77b4", "#ff7f0e", "#9467bd", "#17becf", "#e377c2", "#8c564b",
                   "#bcbd22", "#000000", "#2ca02c", "#393b79", "#8c6d31", "#7b4173",
                   "#637939", "#aec7e8", "#ffbb78", "#c5b0d5")
OUTPOST_COLOUR = "#d62728"
BASE_COLOUR = "#ffffff"
#: viewpoints beyond one battery (crossed out on the overview): dark, not a vehicle's
BEYOND_COLOUR = "#4d4d4d"


def vehicle_colour(vehicle_id: int) -> str:
    """``#rrggbb`` of plan vehicle ``vehicle_id`` (1, 2, ...)."""
    return VEHICLE_COLOURS[(int(vehicle_id) - 1) % len(VEHICLE_COLOURS)]


def kml_colour(rgb: str, alpha: int = 0xFF) -> str:
    """KML's ``aabbggrr`` of ``#rrggbb``."""
    r, g, b = rgb[1:3], rgb[3:5], rgb[5:7]
    return f"{alpha:02x}{b}{g}{r}".lower()
