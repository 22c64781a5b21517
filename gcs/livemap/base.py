"""The live map's base layer: the plan's own hillshade and hidden ceiling, no tiles.

Field laptops are offline, so the page draws nothing from the internet: its base
layer is one PNG made here from the plan's terrain, the same picture as
overview.png's background (hillshade, the hidden ceiling above ground in the
same colours, grey where there is no hidden room). It is reprojected from the
plan's grid onto Web Mercator (EPSG:3857, Leaflet's map projection), so that
Leaflet's image overlay, which stretches an image linearly between two corners
in that projection, puts every pixel where it belongs.
"""

import io

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import LightSource, Normalize
from pyproj import Transformer
from rasterio.crs import CRS
from rasterio.warp import Resampling, calculate_default_transform, reproject

from gcs.plots import CEILING_CMAP

CEILING_ALPHA = 0.45            # as overview.png's overlay
UPSAMPLE = 3                    # base pixels per DEM cell (smooth when zoomed in)
MAX_SIDE = 2400


def base_rgba(terrain, surface) -> tuple:
    """(RGBA uint8 [rows, cols, 4] on the plan's grid, ceiling colour scale (vmin, vmax))."""
    h = np.where(np.isfinite(terrain.height), terrain.height, np.nanmin(terrain.height))
    shade = LightSource(azdeg=315, altdeg=45).hillshade(h, vert_exag=2, dx=terrain.cell_size,
                                                        dy=terrain.cell_size)
    rgb = np.repeat(shade[..., None], 3, axis=2)
    agl = surface.ceiling - terrain.height
    finite = np.isfinite(agl)
    vmax = float(np.nanmax(agl)) if finite.any() else 1.0
    colours = colormaps[CEILING_CMAP](Normalize(0.0, vmax)(np.where(finite, agl, 0.0)))[..., :3]
    rgb = np.where(finite[..., None], (1 - CEILING_ALPHA) * rgb + CEILING_ALPHA * colours, rgb)
    alpha = np.where(np.isfinite(terrain.height), 1.0, 0.0)
    rgba = np.concatenate([rgb, alpha[..., None]], axis=2)
    return (np.clip(rgba * 255 + 0.5, 0, 255).astype(np.uint8), (0.0, vmax))


def base_layer(terrain, surface) -> dict:
    """{"png": bytes, "bounds": [[south, west], [north, east]], "ceiling_agl_m": [0, max]}:
    the base picture in Web Mercator and its corners in degrees."""
    rgba, scale = base_rgba(terrain, surface)
    rows, cols = terrain.shape
    src_crs = CRS.from_user_input(terrain.crs)
    dst_crs = CRS.from_epsg(3857)
    t = terrain.transform
    left, top = t.c, t.f
    right, bottom = left + cols * t.a, top + rows * t.e
    side = min(MAX_SIDE, UPSAMPLE * max(rows, cols))
    scale_up = side / max(rows, cols)
    transform, width, height = calculate_default_transform(
        src_crs, dst_crs, cols, rows, left=left, bottom=bottom, right=right, top=top,
        dst_width=int(round(cols * scale_up)), dst_height=int(round(rows * scale_up)))
    out = np.zeros((4, height, width), np.uint8)
    for band in range(4):
        reproject(rgba[..., band], out[band], src_transform=t, src_crs=src_crs,
                  dst_transform=transform, dst_crs=dst_crs, resampling=Resampling.bilinear,
                  src_nodata=None, dst_nodata=0)
    x0, y0 = transform.c, transform.f
    x1, y1 = x0 + width * transform.a, y0 + height * transform.e
    to_ll = Transformer.from_crs(dst_crs, "EPSG:4326", always_xy=True)
    west, north = to_ll.transform(x0, y0)
    east, south = to_ll.transform(x1, y1)
    return {"png": _png(np.moveaxis(out, 0, 2)), "bounds": [[south, west], [north, east]],
            "ceiling_agl_m": list(scale), "size": [width, height]}


def _png(rgba: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(buf, format="PNG", optimize=False)
    return buf.getvalue()


def ceiling_scale_png(vmax: float, width: int = 160, height: int = 12) -> bytes:
    """The hidden ceiling's colour scale as a small horizontal bar, for the legend."""
    ramp = colormaps[CEILING_CMAP](np.linspace(0, 1, width))[None, :, :]
    grey = np.full_like(ramp, 0.75)
    grey[..., 3] = 1.0
    bar = (1 - CEILING_ALPHA) * grey + CEILING_ALPHA * ramp
    bar[..., 3] = 1.0
    return _png((np.repeat(bar, height, axis=0) * 255).astype(np.uint8))
