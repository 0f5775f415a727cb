"""Trajectory tracks for maps: GeoJSON (RFC 7946 LineString) and KML (LineString, absolute altitude).

Coordinates are ``lon, lat, height`` in degrees and metres on WGS-84, written
in shortest round-trip form.  The GeoJSON feature also carries the sample
times (``properties.time``, seconds in the trajectory's epoch) so that the
track reads back with its times.

Per-point values of the trajectory's extra columns (the 1-sigma and bias
columns of an aided trajectory, :mod:`sinscli.io.aided_columns`) go where each
format allows: GeoJSON ``properties.<column>`` arrays parallel to the
coordinates, with ``properties.units``; KML has no per-vertex attributes on a
LineString, so the Placemark's ``ExtendedData`` holds ``time`` and each column
as a space-separated list in vertex order (``Data name="pos_e_std"``, unit in
``displayName``).  :func:`read_geojson_columns` and :func:`read_kml_columns`
read them back.
"""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from xml.sax.saxutils import escape, quoteattr
from pathlib import Path

import numpy as np

from ..errors import SinsError, printable
from ..types import Trajectory
from . import aided_columns as ac
from .atomic import atomic_path, output_lon_lat

KML_NS = "http://www.opengis.net/kml/2.2"


def _track(path, traj: Trajectory):
    if len(traj) == 0:
        raise SinsError(f"{traj.source}: trajectory is empty; nothing to write")
    lat, lon = output_lon_lat(path, np.degrees(traj.lat), np.degrees(traj.lon), traj.time)   # lon in [-180, 180)
    return lon.tolist(), lat.tolist(), np.asarray(traj.height, dtype=np.float64).tolist()


def _antimeridian_parts(lon: list) -> list[tuple[int, int]]:
    """``[(a, b), ...]``: index ranges of the track between its crossings of the antimeridian (a step of more
    than 180 deg in longitude), which RFC 7946 (3.1.9) asks to cut the line at."""
    cuts = [k + 1 for k in range(len(lon) - 1) if abs(lon[k + 1] - lon[k]) > 180.0]
    edges = [0, *cuts, len(lon)]
    return list(zip(edges[:-1], edges[1:]))


def _columns(traj: Trajectory) -> dict[str, np.ndarray]:
    """``time`` and the extra columns (checked by the guard of
    :func:`sinscli.io.trajectory.write_trajectory`: finite, sigmas positive)."""
    cols = {"time": np.asarray(traj.time, dtype=np.float64)}
    cols.update({c: np.asarray(v, dtype=np.float64) for c, v in traj.extra.items()})
    return cols


def write_geojson(path, traj: Trajectory, conv: int = 0) -> None:
    """A FeatureCollection with one LineString feature (``[lon, lat, height]``) and the times."""
    lon, lat, h = _track(path, traj)
    cols = _columns(traj)
    props = {"name": "sins trajectory", "source": printable(traj.source)}
    props.update({c: v.tolist() for c, v in cols.items()})
    units = {c: ac.UNITS.get(c, "") for c in cols if c != "time"}
    if units:
        props["units"] = {"time": "s", **units}
    points = [list(p) for p in zip(lon, lat, h)]
    parts = _antimeridian_parts(lon)
    geometry = ({"type": "LineString", "coordinates": points} if len(parts) == 1 else
                {"type": "MultiLineString", "coordinates": [points[a:b] for a, b in parts]})  # cut at the antimeridian
    feature = {"type": "Feature", "geometry": geometry, "properties": props}
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump({"type": "FeatureCollection", "features": [feature]}, f, allow_nan=False)


def _line_coords(geometry) -> np.ndarray:
    """The points of a LineString, or of a MultiLineString's parts in order (a track cut at the antimeridian)."""
    c = geometry["coordinates"]
    if geometry["type"] == "MultiLineString":
        c = [p for part in c for p in part]
    return np.array(c, dtype=np.float64)


def read_geojson(path):
    """``(time or None, lat deg, lon deg, height m)`` of the first LineString feature."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        feats = doc["features"] if doc.get("type") == "FeatureCollection" else [doc]
        feat = next(f for f in feats if f["geometry"]["type"] in ("LineString", "MultiLineString"))
        coords = _line_coords(feat["geometry"])
    except (OSError, ValueError, KeyError, TypeError, StopIteration) as exc:
        raise SinsError(f"{path}: not a GeoJSON file with a LineString feature ({type(exc).__name__})") from None
    if coords.ndim != 2 or coords.shape[1] < 2:
        raise SinsError(f"{path}: LineString coordinates must be [lon, lat(, height)] pairs")
    t = feat.get("properties", {}).get("time")
    t = np.array(t, dtype=np.float64) if t is not None else None
    h = coords[:, 2] if coords.shape[1] > 2 else np.zeros(coords.shape[0])
    return t, coords[:, 1], coords[:, 0], h


def read_geojson_columns(path) -> dict[str, np.ndarray]:
    """Per-point columns of the first LineString feature: ``time`` and every property array of its length."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        feats = doc["features"] if doc.get("type") == "FeatureCollection" else [doc]
        feat = next(f for f in feats if f["geometry"]["type"] in ("LineString", "MultiLineString"))
        n = len(_line_coords(feat["geometry"]))
        props = feat.get("properties") or {}
        out = {k: np.array(v, dtype=np.float64) for k, v in props.items()
               if isinstance(v, list) and len(v) == n and all(isinstance(x, (int, float)) for x in v)}
    except (OSError, ValueError, KeyError, TypeError, StopIteration) as exc:
        raise SinsError(f"{path}: not a GeoJSON file with a LineString feature ({type(exc).__name__})") from None
    ac.check_columns(str(path), out, first_row=0, row_label="point")
    return out


def write_kml(path, traj: Trajectory, conv: int = 0) -> None:
    """A KML document with one Placemark LineString (absolute altitude), extra columns in ExtendedData."""
    lon, lat, h = _track(path, traj)
    cols = _columns(traj)
    coords = " ".join(f"{a!r},{b!r},{c!r}" for a, b, c in zip(lon, lat, h))
    extended = ""
    if traj.extra:
        items = []
        for c, v in cols.items():
            unit = "s" if c == "time" else ac.UNITS.get(c, "")
            label = f"{c} ({unit})" if unit else c
            items.append(f'<Data name={quoteattr(c)}><displayName>{escape(label)}</displayName><value>'
                         + " ".join(repr(x) for x in v.tolist()) + "</value></Data>\n")
        extended = "<ExtendedData>\n" + "".join(items) + "</ExtendedData>\n"
    name = printable(traj.source).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write('<?xml version="1.0" encoding="UTF-8"?>\n'
                    f'<kml xmlns="{KML_NS}">\n<Document>\n<name>sins trajectory</name>\n'
                    f'<description>{name}</description>\n'
                    '<Style id="track"><LineStyle><color>ff0000ff</color><width>3</width></LineStyle></Style>\n'
                    '<Placemark>\n<name>sins trajectory</name>\n<styleUrl>#track</styleUrl>\n'
                    + extended + '<LineString>\n<altitudeMode>absolute</altitudeMode>\n<coordinates>')
            f.write(coords)
            f.write("</coordinates>\n</LineString>\n</Placemark>\n</Document>\n</kml>\n")


def read_kml(path):
    """``(lat deg, lon deg, height m)`` of the first LineString of a KML file."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
        node = root.find(f".//{{{KML_NS}}}LineString/{{{KML_NS}}}coordinates")
        text = node.text
        pts = np.array([[float(v) for v in p.split(",")] for p in text.split()], dtype=np.float64)
    except (OSError, ET.ParseError, AttributeError, ValueError) as exc:
        raise SinsError(f"{path}: not a KML file with a LineString ({type(exc).__name__})") from None
    if pts.ndim != 2 or pts.shape[1] < 2:
        raise SinsError(f"{path}: LineString coordinates must be lon,lat(,height) triples")
    h = pts[:, 2] if pts.shape[1] > 2 else np.zeros(pts.shape[0])
    return pts[:, 1], pts[:, 0], h


def read_kml_columns(path) -> dict[str, np.ndarray]:
    """The per-vertex lists of the first Placemark's ExtendedData (``time`` and the extra columns)."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
        pm = root.find(f".//{{{KML_NS}}}Placemark")
        out = {}
        for d in pm.findall(f"{{{KML_NS}}}ExtendedData/{{{KML_NS}}}Data"):
            text = d.find(f"{{{KML_NS}}}value").text or ""
            out[d.get("name")] = np.array([float(x) for x in text.split()], dtype=np.float64)
    except (OSError, ET.ParseError, AttributeError, ValueError) as exc:
        raise SinsError(f"{path}: not a KML file with a Placemark ({type(exc).__name__})") from None
    ac.check_columns(str(path), out, first_row=0, row_label="vertex")
    return out
