"""An answer in plain words: which area the user is in, what is near, what they face.

Places are points with a name; a place with an `area` [x0, y0, x1, y1] is also a region one can be
*in* (a corridor, a hall). Bearings are relative to the user's heading, clockwise, in (-180, 180].

The phone makes the words the user hears (web/src/client/directions.ts), in the user's chosen
style and offline too; the answer's `sentence` is the same sentence in the default style, for API
clients. Both read the thresholds and fixed sentences from one file, words.json, and are pinned by one
table of cases, tests/data/sentences.json, which holds the thresholds too.

Route guidance (route.py makes the numbers: bearing, metres, what is at the end) is worded here
too, by `guidance_sentence` and `preview_sentence`, pinned with the app's words by
tests/data/guidance.json in the same way.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

from .aggregate import SURE

# the thresholds and fixed sentences, read with the phone (directions.ts) from one file
WORDS: dict[str, Any] = json.loads((Path(__file__).parent / "words.json").read_text())
NEAR_M = float(WORDS["near_m"])  # a landmark further than this is not "near"
# nor one nearer than this "near ... at 3 o'clock": the user is *at* it. Under a metre the way to
# it is noise (the answer's own error is about that), and, said every few seconds to someone
# standing there, it turned round the clock and was said again each time
AT_M = float(WORDS["at_m"])
FACING_M = float(WORDS["facing_m"])  # nor one this far "faced"
FACING_DEG = float(WORDS["facing_deg"])  # and "facing" means within this angle of the heading
UNSURE: str = WORDS["unsure"]
# An answer under SURE (aggregate.py's: the confidence's promise in docs/formats.md, of the answers
# at or above it at least 80 % within 2 m, and the app's "film on" line), though not "not sure",
# is said as "You are probably ...": under it a fifth to two fifths of the answers are further than 2 m off on the
# venue families we never tuned on, against 1-2 % above it (docs/benchlog.md, "Said as
# probably"), and a user who hears a place as a fact walks off on it.

Style = Literal["clock", "sides", "degrees"]
DEFAULT_STYLE: Style = "clock"


def relative_bearing(x: float, y: float, heading: float, px: float, py: float) -> float:
    """Clockwise angle from the heading to the point, in (-180, 180] (plan: y down, 0 = up)."""
    b = math.degrees(math.atan2(px - x, -(py - y)))
    return _signed(b - heading)


def _signed(b: float) -> float:
    """Any angle -> (-180, 180]."""
    r = (b + 180.0) % 360.0 - 180.0
    return 180.0 if r == -180.0 else r


def _round(v: float) -> int:
    """Half up, as JavaScript's Math.round (Python's round() goes half to even)."""
    return math.floor(v + 0.5)


def clock_hour(bearing: float) -> int:
    """-> 1..12, 12 straight ahead. A bearing on a boundary (15, 45, ...) takes the hour nearer
    straight ahead, on either side, so left and right mirror each other."""
    b = _signed(bearing)
    h = math.ceil(abs(b) / 30.0 - 0.5)
    return (12 - h if b < 0 else h) % 12 or 12


# the sides style's sector limits: straight ahead | ahead on a side | beside | behind on a side | behind
SECTOR_DEG: tuple[float, ...] = tuple(float(v) for v in WORDS["sector_deg"])


def sector(bearing: float) -> int:
    """The sides style's sector of a bearing: 0 straight ahead, 1 ahead on a side, 2 beside, 3 behind on
    a side, 4 behind (both `direction` and `turn_phrase` word it). A bearing on a boundary belongs to
    the sector nearer straight ahead, on either side."""
    a = abs(_signed(bearing))
    return next((k for k, limit in enumerate(SECTOR_DEG) if a <= limit), len(SECTOR_DEG))


def direction(bearing: float, style: Style) -> str:
    """'at 3 o'clock' | 'to your right' | 'at 90 degrees to your right': a phrase that follows a place name."""
    b = _signed(bearing)
    side = "right" if b > 0 else "left"
    a = abs(b)
    if style == "clock":
        return f"at {clock_hour(b)} o'clock"
    if style == "degrees":
        d = _round(a)
        if d == 0:
            return "straight ahead"
        if d == 180:
            return "straight behind you"
        return f"at {d} {'degree' if d == 1 else 'degrees'} to your {side}"
    return ("straight ahead", f"ahead on your {side}", f"to your {side}", f"behind you on your {side}", "behind you")[
        sector(b)
    ]


def with_article(name: str) -> str:
    """'North corridor' -> 'the North corridor'; 'Corridor 1', 'the hall', 'Hall B' stay as they are."""
    words = name.split()
    last = words[-1] if words else ""
    first = last[:1]
    if name.lower().startswith("the ") or (first.isascii() and first.isdigit()) or (len(last) == 1 and last.isupper()):
        return name
    return f"the {name}"


def metres(d: float) -> str:
    m = max(1, _round(d))
    return "1 metre" if m == 1 else f"{m} metres"


def sentence(answer: Mapping[str, Any], style: Style = DEFAULT_STYLE, floor_name: str | None = None) -> str:
    """The sentence to speak for an answer (its area, nearest, facing, floor, low_confidence and
    confidence: under SURE it is "You are probably ..."). Outside every area with no place within
    NEAR_M, the floor and how far the nearest place is, and which way: "on the floor" alone is
    nothing a blind user can act on."""
    if answer["low_confidence"]:
        return UNSURE
    n = answer["nearest"]
    near = n if n and n["distance_m"] <= NEAR_M else None
    parts = []
    if answer["area"]:
        parts.append(f"in {with_article(answer['area'])}")
    if near and near["distance_m"] < AT_M:
        parts.append(f"at {near['name']}")
    elif near:
        parts.append(f"near {near['name']} {direction(near['bearing_deg'], style)}, {metres(near['distance_m'])}")
    far = None
    if not parts:  # never the floor alone where the floor has a place: how far the nearest is, and where
        parts.append(f"on {floor_name if floor_name is not None else 'floor ' + answer['floor']}")
        if n:
            far = n
            parts.append(f"{metres(n['distance_m'])} from {n['name']} {direction(n['bearing_deg'], style)}")
    facing = answer["facing"]
    named = near or far
    if facing and not (named and facing == named["name"]):
        parts.append(f"facing {facing}")
    probably = "" if answer["confidence"] >= SURE else "probably "  # (NaN: probably)
    return f"You are {probably}{', '.join(parts)}."


def _inside(p: Mapping[str, Any], x: float, y: float) -> bool:
    a = p.get("area")
    return a is not None and a[0] <= x <= a[2] and a[1] <= y <= a[3]


def describe(
    x: float,
    y: float,
    heading: float,
    places: list[dict[str, Any]],
    floor_name: str,
    low: bool = False,
    confidence: float = 1.0,
) -> dict[str, Any]:
    """The answer's words for a pose on a floor: {place, area, nearest: {name, distance_m,
    bearing_deg} | None, facing, sentence}. A low-confidence answer keeps the fields but says UNSURE;
    one under SURE says "You are probably ..."."""
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
    words: dict[str, Any] = {
        "area": area["name"] if area else None,
        "nearest": nearest,
        "facing": min(ahead)[2] if ahead else None,
    }
    # the place the answer is at: a near landmark, else the area, else the nearest landmark however far
    near = nearest if nearest and nearest["distance_m"] <= NEAR_M else None
    words["place"] = near["name"] if near else words["area"] or (nearest and nearest["name"])
    words["sentence"] = sentence({**words, "low_confidence": low, "confidence": confidence}, DEFAULT_STYLE, floor_name)
    return words


# --- route guidance (route.py makes the numbers; these are its words) ---------------------------
# Pinned with the app's directions.ts by one table, tests/data/guidance.json.

STRAIGHT_DEG = SECTOR_DEG[0]  # a bearing within this of straight ahead is "straight ahead": no turn
# the sides style's turn beyond this is "Turn around", not "Turn sharp left" at 161
AROUND_DEG = float(WORDS["around_deg"])
GUIDE_UNSURE: str = WORDS["guide_unsure"]
GUIDE_NOT_HERE: str = WORDS["guide_not_here"]


def turn_phrase(bearing: float, style: Style) -> str | None:
    """'Turn to 2 o'clock' | 'Turn right' | 'Turn 60 degrees right'; None within STRAIGHT_DEG."""
    b = _signed(bearing)
    side = "right" if b > 0 else "left"
    k = sector(b)
    if k == 0:
        return None
    if style == "clock":
        return f"Turn to {clock_hour(b)} o'clock"
    if style == "degrees":
        d = _round(abs(b))
        return "Turn around" if d >= 180 else f"Turn {d} degrees {side}"
    if abs(b) > AROUND_DEG:  # a turn this near round is "around", though a place there is "behind you on a side"
        return "Turn around"
    return (f"Bear {side}", f"Turn {side}", f"Turn sharp {side}", "Turn around")[k - 1]


def instruction(bearing: float, walk_m: float, until: str | None, style: Style, in_m: float | None = None) -> str:
    """'Turn to 2 o'clock and walk 12 metres, to the end of the corridor.' (straight ahead: 'Walk
    straight ahead 12 metres, to ...'). With `in_m`, the metres still to walk to the corner where
    the turn is: 'In 3 metres, turn to 2 o'clock and walk 12 metres, ...' (none when it rounds to 0)."""
    tail = f", to {until}" if until else ""
    turn = turn_phrase(bearing, style)
    said = (
        f"Walk straight ahead {metres(walk_m)}{tail}." if turn is None else f"{turn} and walk {metres(walk_m)}{tail}."
    )
    if in_m is None or _round(in_m) < 1:
        return said
    return f"In {metres(in_m)}, {said[0].lower()}{said[1:]}"


def guidance_sentence(g: Mapping[str, Any], style: Style = DEFAULT_STYLE) -> str:
    """The sentence for a guidance (route.py's JSON: kind, bearing_deg, walk_m, until, in_m,
    floor_change, to {name, say?})."""
    kind = g["kind"]
    if kind == "unsure":
        return GUIDE_UNSURE
    if kind == "not_here":
        return GUIDE_NOT_HERE
    b = g["bearing_deg"]
    if kind in ("arrived", "probably_arrived"):
        at = "You have arrived at" if kind == "arrived" else "You are probably at"
        if g["walk_m"] < 0.5:  # at the place itself: it has no bearing
            said = f"{at} {g['to']['name']}."
        else:
            said = f"{at} {g['to']['name']}; it is {direction(b, style)}, {metres(g['walk_m'])}."
        say = g["to"].get("say")
        return f"{said} {say}" if say else said
    if kind == "off_route":
        turn = turn_phrase(b, style)
        return f"You are off the route; {turn[0].lower() + turn[1:] if turn else 'walk straight ahead'}."
    fc = g.get("floor_change")
    if fc:
        return f"Take the {fc['via']} to {fc['to_floor_name']}."
    if kind in ("reassure", "back_on_route"):
        on = f"{metres(g['walk_m'])}" + (f" to {g['until']}" if g["until"] else "") + "."
        return f"You are on the route again; keep going, {on}" if kind == "back_on_route" else f"Keep going, {on}"
    return instruction(b, g["walk_m"], g["until"], style, g.get("in_m"))


def preview_sentence(p: Mapping[str, Any], to: Mapping[str, Any]) -> str:
    """A route before starting: 'Room 102: 45 metres, 2 turns, first turn after 12 metres.'"""
    name = str(to["name"])
    name = name[:1].upper() + name[1:]  # the sentence starts with it: "The lifts: ..."
    n = p["turns"]
    if p["length_m"] < 1 and n == 0:
        return f"{name}: you are there."
    parts = [metres(p["length_m"])]
    if n == 0:
        parts.append("no turns")
    elif n == 1:
        parts.append(f"1 turn, after {metres(p['first_turn_m'])}")
    else:
        parts.append(f"{n} turns, first turn after {metres(p['first_turn_m'])}")
    floors = len(set(p.get("floors") or ()))
    if floors > 1:
        parts.append(f"on {floors} floors")
    return f"{name}: {', '.join(parts)}."
