"""The vertical units a DEM's heights may be in: what `--z-unit` takes, and the names
GDAL, PROJ and people write them with. Light: imported by the option parser."""

#: metres per unit, by the name `--z-unit` takes: the international foot is exactly
#: 0.3048 m; the US survey foot is 1200/3937 m (EPSG:9003)
Z_UNITS = {"m": 1.0, "ft": 0.3048, "us-ft": 1200.0 / 3937.0}
#: how a warning names them
Z_UNIT_WORDS = {"m": "metres", "ft": "feet", "us-ft": "US survey feet"}

_SPELLINGS = {
    "m": ("m", "metre", "metres", "meter", "meters", "masl"),
    "ft": ("ft", "foot", "feet", "international foot", "international feet", "intl foot",
           "ft intl", "foot international", "international ft"),
    "us-ft": ("us-ft", "us ft", "usft", "ftus", "ft us", "us foot", "us feet", "foot us",
              "us survey foot", "us survey feet", "survey foot", "survey feet",
              "us survey ft", "sft", "foot us survey"),
}
#: words after the unit that say what is measured, not in what
_QUALIFIERS = ("above mean sea level", "above sea level", "amsl", "asl", "msl")
_BY_SPELLING = {s: unit for unit, spellings in _SPELLINGS.items() for s in spellings}


def z_unit_of(text):
    """The `Z_UNITS` key a unit's name means (case, dots, dashes, underscores and
    brackets aside: 'US survey foot', 'ftUS', 'Foot_US', 'metre'), or None for a name
    that is none of them (an unknown or non-length unit, e.g. 'furlong', 'degC')."""
    words = str(text).lower().replace(".", "")
    for c in "_-()[]/,":
        words = words.replace(c, " ")
    words = " ".join(words.split())
    for qualifier in _QUALIFIERS:  # 'm AMSL', 'metres above sea level'
        if words.endswith(" " + qualifier):
            words = words[: -len(qualifier) - 1]
            break
    return _BY_SPELLING.get(words)


def z_unit_of_factor(metres_per_unit: float):
    """The `Z_UNITS` key of a unit of this many metres (as PROJ gives a CRS axis's),
    or None."""
    for unit, factor in Z_UNITS.items():
        if abs(float(metres_per_unit) - factor) <= 1e-12:
            return unit
    return None
