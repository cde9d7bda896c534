"""An answer in plain words: which area the user is in, what is near, what they face.

Places are points with a name; a place with an `area` [x0, y0, x1, y1] is also a region one can be
*in* (a corridor, a hall). Bearings are relative to the user's heading, clockwise, in (-180, 180]:
the phone turns them into clock faces or left/right in the user's chosen style.
"""

from __future__ import annotations

import math
from typing import Any

NEAR_M = 10.0  # a landmark further than this is not "near"
FACING_M = 30.0  # nor one this far "faced"
FACING_DEG = 30.0  # and "facing" means within this angle of the heading
UNSURE = "Not sure where you are; turn slowly and try again."


def relative_bearing(x: float, y: float, heading: float, px: float, py: float) -> float:
    """Clockwise angle from the heading to the point, in (-180, 180] (plan: y down, 0 = up)."""
    b = math.degrees(math.atan2(px - x, -(py - y)))
    r = (b - heading + 180.0) % 360.0 - 180.0
    return 180.0 if r == -180.0 else r


def _with_article(name: str) -> str:
    """'North corridor' -> 'the North corridor'; 'Corridor 1', 'the hall', 'Hall B' stay as they are."""
    last = name.split()[-1] if name.split() else ""
    if name.lower().startswith("the ") or last[:1].isdigit() or (len(last) == 1 and last.isupper()):
        return name
    return f"the {name}"


def _inside(p: dict[str, Any], x: float, y: float) -> bool:
    a = p.get("area")
    return a is not None and a[0] <= x <= a[2] and a[1] <= y <= a[3]


def describe(x: float, y: float, heading: float, places: list[dict[str, Any]], floor_name: str) -> dict[str, Any]:
    """-> {area, nearest: {name, distance_m, bearing_deg}|None, facing, sentence} for a confident answer."""
    areas = [p for p in places if _inside(p, x, y)]
    # the smallest area that holds the point: a room inside a wing says more than the wing
    area = min(areas, key=lambda p: (p["area"][2] - p["area"][0]) * (p["area"][3] - p["area"][1]), default=None)
    points = [p for p in places if not p.get("area")]
    dist = [math.hypot(p["x"] - x, p["y"] - y) for p in points]
    nearest = None
    if points:
        i = min(range(len(points)), key=dist.__getitem__)
        p = points[i]
        nearest = {
            "name": p["name"],
            "distance_m": round(dist[i], 1),
            "bearing_deg": round(relative_bearing(x, y, heading, p["x"], p["y"]), 1),
        }
    ahead = [
        (abs(relative_bearing(x, y, heading, p["x"], p["y"])), d, p["name"])
        for p, d in zip(points, dist, strict=True)
        if 1.0 < d <= FACING_M and abs(relative_bearing(x, y, heading, p["x"], p["y"])) <= FACING_DEG
    ]
    facing = min(ahead)[2] if ahead else None
    parts = []
    if area:
        parts.append(f"in {_with_article(area['name'])}")
    if nearest and nearest["distance_m"] <= NEAR_M:
        parts.append(f"near {nearest['name']}")
    sentence = "You are " + (", ".join(parts) if parts else f"on {floor_name}")
    if facing and not (nearest and facing == nearest["name"] and nearest["distance_m"] <= NEAR_M):
        sentence += f", facing {facing}"
    return {
        "area": area["name"] if area else None,
        "nearest": nearest,
        "facing": facing,
        "sentence": sentence + ".",
    }
