"""The one top-down drawing of a scene and what moves on it (PIL, no display), in the colours of `sim/palette.py`.

Layers, bottom up: ground, roads (islands, lane lines), sidewalks (every zone, or buildings only), crosswalks and
curb ramps, terrain patches by surface (stairs outlined, a line on each riser), objects by object class, route,
trajectory, vehicles, agents with trails, ego. Three callers differ only in window, resolution and decoration: the
scene plot (`sim.scene.plot.render_scene`, a PNG with axes and legend), the agents' map frame
(`sim.agents.map_frame.draw_top_down`, `SocialNav render()`) and the rollout GIF (`sim.frames.rollout_gif`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import numpy as np
from PIL import Image, ImageDraw

from sim.palette import (
    CLEAR_PATH,
    EDGE,
    EGO,
    ISLAND,
    LANE_LINE,
    OBJECT,
    OBJECT_CLASS,
    OUTLINE,
    ROUTE,
    SURFACE,
    VEHICLE,
    ZONE,
    rgb255,
    terrain_colour,
)
from sim.scene.scene import Scene
from sim.terrain.patches import riser_lines

Colour = tuple[float, ...]  # RGB(A) floats in [0, 1], as in sim/palette.py


class Surface(Protocol):
    """What the layers draw on: a `Canvas` (pixels) or the scene plot's `PlotCanvas` (a matplotlib Axes)."""

    px_per_m: float

    def polygon(self, pts: Any, fill: Colour | None, outline: Colour | None = None, width: float = 1.0) -> None:
        """A polygon filled with `fill` (None: not filled), outlined `width` pixels wide when `outline` is given."""

    def line(self, pts: Any, colour: Colour, width: float = 1.0, dash: tuple[float, float] | None = None) -> None:
        """A polyline `width` pixels wide; `dash` = (on, off) metres draws it dashed."""

    def disc(self, x: float, y: float, r: float, fill: Colour, outline: Colour | None = None) -> None:
        """A disc of radius `r` metres at (x, y)."""


class Canvas:
    """An RGB picture of the world window `extent` = (x0, y0, x1, y1) m, y up, at `px_per_m` pixels a metre.

    It draws `ss` times larger and shrinks in `image()`: PIL does not antialias, supersampling does. Widths
    and radii given in pixels are output pixels. `background` (an RGB array of the output size) is drawn over.
    """

    def __init__(
        self, extent: Sequence[float], px_per_m: float, *, ss: int = 1, background: np.ndarray | None = None
    ) -> None:
        self.x0, self.y0, self.x1, self.y1 = (float(v) for v in extent)
        self.px_per_m, self.ss = float(px_per_m), int(ss)
        if background is not None:
            self.size = (background.shape[1], background.shape[0])
            img = Image.fromarray(background).resize((self.size[0] * self.ss, self.size[1] * self.ss))
        else:
            self.size = (max(1, round((self.x1 - self.x0) * px_per_m)), max(1, round((self.y1 - self.y0) * px_per_m)))
            img = Image.new("RGB", (self.size[0] * self.ss, self.size[1] * self.ss), rgb255(SURFACE["ground"]))
        self.img, self.scale = img, self.px_per_m * self.ss
        self.draw = ImageDraw.Draw(img)

    def px(self, pts: Any) -> list[tuple[float, float]]:
        """World points (N, 2) as pixel coordinates of the drawing."""
        if isinstance(pts, np.ndarray):
            pts = pts.reshape(-1, 2).tolist()
        x0, y1, k = self.x0, self.y1, self.scale  # plain Python: specs hold short lists, numpy costs more there
        return [((x - x0) * k, (y1 - y) * k) for x, y in pts]

    def polygon(self, pts: Any, fill: Colour | None, outline: Colour | None = None, width: float = 1.0) -> None:
        """A polygon filled with `fill` (None: not filled), outlined `width` pixels wide when `outline` is given."""
        xy = self.px(pts)
        if len(xy) < 3:
            return
        self.draw.polygon(
            xy,
            fill=None if fill is None else rgb255(fill),
            outline=None if outline is None else rgb255(outline),
            width=max(1, round(width * self.ss)),
        )

    def line(self, pts: Any, colour: Colour, width: float = 1.0, dash: tuple[float, float] | None = None) -> None:
        """A polyline `width` pixels wide; `dash` = (on, off) metres draws it dashed."""
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
        w = max(1, round(width * self.ss))
        for piece in [pts] if dash is None else dashes(pts, *dash):
            if len(piece) > 1:
                self.draw.line(self.px(piece), fill=rgb255(colour), width=w, joint="curve")

    def disc(self, x: float, y: float, r: float, fill: Colour, outline: Colour | None = None) -> None:
        """A disc of radius `r` metres at (x, y)."""
        ((u, v),) = self.px([(x, y)])
        rp = r * self.scale
        self.draw.ellipse(
            [u - rp, v - rp, u + rp, v + rp],
            fill=rgb255(fill),
            outline=None if outline is None else rgb255(outline),
            width=self.ss,
        )

    def image(self) -> np.ndarray:
        """The drawing as an RGB (H, W, 3) uint8 array of the output size."""
        img = self.img if self.ss == 1 else self.img.resize(self.size, Image.Resampling.BOX)
        return np.asarray(img).copy()


def object_colour(obj: dict[str, Any]) -> Colour:
    """An object's colour on the map: its object class's (building facades apart), as the scene plot's legend says."""
    if obj.get("category") == "building_facade":
        return OBJECT_CLASS["building"]
    return OBJECT_CLASS.get(str(obj.get("object_class")), OBJECT)


def draw_scene(c: Surface, scene: Scene | Mapping[str, Any], *, zones: bool = False) -> None:
    """Roads, islands, lane lines, sidewalks, crosswalks, ramps, terrain and objects; `zones` colours every zone.

    Without `zones` (the frames) a sidewalk is one surface with its buildings; with it (the scene plot) each
    zone has its colour and curbs, clear paths and outlines are drawn.
    """
    # The records only are drawn: a dict is read as it is, never parsed, since frames redraw it every step.
    spec = scene.spec if isinstance(scene, Scene) else scene
    edge = EDGE if zones else None
    for road in spec.get("roads", []):
        c.polygon(road["polygon"], SURFACE["road"])
        if road.get("island"):
            c.polygon(road["island"], ISLAND, EDGE)
    for road in spec.get("roads", []):
        for lane in road.get("lane_lines", []):
            c.line(lane, LANE_LINE, 1.0, dash=(3.0, 3.0))
    for sw in spec.get("sidewalks", []):
        c.polygon(sw["polygon"], SURFACE["sidewalk"])
        for zone in sw.get("zones", []):
            if zones or zone.get("kind") == "building":
                c.polygon(zone["polygon"], ZONE.get(zone.get("kind"), SURFACE["sidewalk"]), edge, 0.5)
        if zones and sw.get("edge"):
            c.line(sw["edge"], EDGE, 1.5)
        if zones and sw.get("clear_path"):
            c.line(sw["clear_path"], CLEAR_PATH, 1.0, dash=(0.5, 1.0))
    for cw in spec.get("crosswalks", []):
        c.polygon(cw["polygon"], SURFACE["road"])
        for bar in _zebra(cw["polygon"]):
            c.polygon(bar, SURFACE["crosswalk"])
        if zones:
            c.polygon(cw["polygon"], None, EDGE)
        for ramp in cw.get("ramps", []):
            c.polygon(ramp["polygon"], SURFACE["ramp"], edge, 0.5)
    for patch in spec.get("terrain", []):
        stair = patch["kind"] == "steps"
        c.polygon(patch["footprint"], terrain_colour(patch["kind"], patch["surface"]), EDGE if stair else edge, 0.5)
        for riser in riser_lines(patch):
            c.line(riser, EDGE, 1.0)
    for obj in spec.get("objects", []):
        if obj.get("footprint"):
            c.polygon(obj["footprint"], object_colour(obj), edge, 0.5)


def draw_route(c: Surface, route: Any, width: float = 2.0, goal: bool = False) -> None:
    """The reference route as a line `width` pixels wide, with a star on the goal when `goal`."""
    pts = np.asarray(route, dtype=np.float64).reshape(-1, 2)
    c.line(pts, ROUTE, width)
    if goal and len(pts):
        radius = 7.0 / c.px_per_m  # a 7-pixel star, whatever the scale
        angles = np.pi / 2 + np.arange(10) * np.pi / 5
        rad = np.where(np.arange(10) % 2 == 0, radius, 0.4 * radius)
        c.polygon(pts[-1] + np.c_[rad * np.cos(angles), rad * np.sin(angles)], ROUTE)


def box(x: float, y: float, yaw: float, length: float, width: float) -> np.ndarray:
    """The four corners (4, 2) of a `length` x `width` rectangle centred at (x, y), heading `yaw`."""
    cos, sin = math.cos(yaw), math.sin(yaw)
    corners = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * [length / 2, width / 2]
    return corners @ np.array([[cos, sin], [-sin, cos]]) + [x, y]


def draw_vehicles(c: Surface, vehicles: Any) -> None:
    """Vehicles (fields x, y, yaw, length, width) as boxes."""
    for v in vehicles:
        c.polygon(box(v["x"], v["y"], v["yaw"], v["length"], v["width"]), VEHICLE)


def draw_agents(c: Surface, agents: Any, colours: Sequence[Colour], trails: np.ndarray | None = None) -> None:
    """Agents (fields x, y, radius) as outlined discs in `colours`, over their faded `trails` (T, N, 2)."""
    if trails is not None:
        for i, col in enumerate(colours):
            c.line(trails[:, i], tuple(0.5 * v + 0.5 for v in col[:3]), max(1.0, 0.12 * c.px_per_m))
    for a, col in zip(agents, colours):
        c.disc(float(a["x"]), float(a["y"]), float(a["radius"]), col, OUTLINE)


def draw_ego(
    c: Surface, x: float, y: float, yaw: float, length: float, width: float, colour: Colour = EGO, min_px: float = 8.0
) -> None:
    """The ego machine as an outlined box with a heading tick, grown to `min_px` pixels long where smaller."""
    grow = max(1.0, min_px / (length * c.px_per_m))
    c.polygon(box(x, y, yaw, length * grow, width * grow), colour, OUTLINE)
    tip = 0.5 * length * grow + 4.0 / c.px_per_m
    c.line([[x, y], [x + tip * math.cos(yaw), y + tip * math.sin(yaw)]], OUTLINE, 2.0)


def _zebra(polygon: Any, bar: float = 0.5) -> list[np.ndarray]:
    """The white bars of a zebra crossing, `bar` m wide and apart along its long sides (all of it unless a quad)."""
    quad = np.asarray(polygon, dtype=np.float64)
    if len(quad) != 4:
        return [quad]
    if np.hypot(*(quad[1] - quad[0])) < np.hypot(*(quad[2] - quad[1])):
        quad = np.roll(quad, -1, axis=0)  # q0 -> q1 and q3 -> q2 are now the long sides, the walking direction
    length = 0.5 * (np.hypot(*(quad[1] - quad[0])) + np.hypot(*(quad[2] - quad[3])))
    n_bars = int((length + bar) // (2 * bar))
    start = 0.5 * (length - (2 * n_bars - 1) * bar)
    bars = []
    for i in range(n_bars):
        t0, t1 = (start + 2 * bar * i) / length, (start + 2 * bar * i + bar) / length
        bars.append(
            np.array(
                [
                    quad[0] + t0 * (quad[1] - quad[0]),
                    quad[0] + t1 * (quad[1] - quad[0]),
                    quad[3] + t1 * (quad[2] - quad[3]),
                    quad[3] + t0 * (quad[2] - quad[3]),
                ]
            )
        )
    return bars


def dashes(pts: np.ndarray, on: float, off: float) -> list[np.ndarray]:
    """The `on`-metre pieces of a polyline, `off` metres apart along its arc length."""
    arclen = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    starts = np.arange(0.0, arclen[-1], on + off)
    stops = np.minimum(starts + on, arclen[-1])
    # Both ends of every dash at once (frames redraw the lane lines every step); inner vertices where bent.
    ends = np.stack(
        [
            np.stack([np.interp(bound, arclen, pts[:, 0]), np.interp(bound, arclen, pts[:, 1])], -1)
            for bound in (starts, stops)
        ],
        1,
    )
    if len(pts) == 2:
        return list(ends)
    return [
        np.vstack([end_pts[:1], pts[(arclen > lo) & (arclen < hi)], end_pts[1:]])
        for end_pts, lo, hi in zip(ends, starts, stops)
    ]
