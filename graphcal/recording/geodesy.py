"""WGS-84 latitude/longitude to a local east-north frame, with pymap3d.

``pymap3d`` is a small, maintained pure-Python geodesy library; its ``geodetic2enu`` is the
exact ellipsoidal conversion, vectorized over numpy arrays. The altitude is taken as 0 for
every fix: graphcal's model is planar, and a logged altitude would only tilt the frame.
"""

from __future__ import annotations

import numpy as np

from graphcal.errors import GraphcalError


class GeodesyError(GraphcalError, ValueError):
    """Latitude/longitude that cannot be fixes on Earth; one line: what, where, how to fix."""


def check_geodetic(
    latitude: np.ndarray, longitude: np.ndarray, source: str, provenance=None
) -> None:
    """Raise :class:`GeodesyError` for latitudes outside ±90° or longitudes outside ±180°.

    ``provenance`` (:class:`graphcal.recording.streams.Provenance`) names the file's columns and
    the sample's line; without it, the sample's number in ``source``.
    """
    for name, values, limit in (("latitude", latitude, 90.0), ("longitude", longitude, 180.0)):
        bad = ~np.isfinite(values) | (np.abs(values) > limit)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            hint = (
                "latitude and longitude look swapped; exchange the two columns"
                if name == "latitude" and np.all(np.abs(longitude) <= 90.0)
                else f"give the {name} in degrees WGS-84"
            )
            where = (
                f"{source}: {name} of sample {k + 1}"
                if provenance is None
                else f"{provenance.at((name,), k)}: {name}"
            )
            raise GeodesyError(f"{where} is {values[k]:.9g}°, outside ±{limit:g}°; {hint}")


def geodetic_to_local(
    latitude: np.ndarray,
    longitude: np.ndarray,
    source: str,
    origin: tuple[float, float] | None = None,
    *,
    provenance=None,
) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """East and north [m] of each fix from ``origin`` (default: the first fix).

    Args:
        latitude, longitude: WGS-84 [deg], ``(M,)``.
        source: name of the stream, for messages.
        origin: ``(latitude, longitude)`` [deg] of the local frame's origin.
        provenance: the file's columns and lines, for messages (:func:`check_geodetic`).

    Returns:
        ``(east, north, origin)``.
    """
    import pymap3d

    latitude = np.asarray(latitude, dtype=float)
    longitude = np.asarray(longitude, dtype=float)
    check_geodetic(latitude, longitude, source, provenance)
    if origin is None:
        origin = (float(latitude[0]), float(longitude[0]))
    east, north, _ = pymap3d.geodetic2enu(
        latitude, longitude, np.zeros_like(latitude), origin[0], origin[1], 0.0
    )
    return np.asarray(east, dtype=float), np.asarray(north, dtype=float), origin


def local_to_geodetic(
    east: np.ndarray, north: np.ndarray, origin: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Latitude and longitude [deg] of local east/north positions [m] around ``origin``."""
    import pymap3d

    east = np.asarray(east, dtype=float)
    latitude, longitude, _ = pymap3d.enu2geodetic(
        east, np.asarray(north, dtype=float), np.zeros_like(east), origin[0], origin[1], 0.0
    )
    return np.asarray(latitude, dtype=float), np.asarray(longitude, dtype=float)
