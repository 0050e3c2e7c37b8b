"""Vehicles on roads: IDM car following along lane polylines offset from road centerlines, turning through
intersections, yielding at crosswalks and taking turns where paths cross.

Lanes: `lanes` per direction (the spec's road half width is lanes * lane_width); right lanes run along the
centerline's direction, left lanes against it; connectors are Bezier paths through X and T junctions from
each arriving lane to each leaving lane of another arm (geometry in sim.agents.lanes). Every vehicle carries
its next lane, drawn when it enters a lane among the lane's successors (its continuation into the next
block, or the junction's connectors: straight on, left, right), and IDM looks one lane ahead: the rearmost
vehicle and any occupied crosswalk on the next lane are leaders too (Treiber, Hennecke & Helbing 2000).
A junction is entered on a grant: a vehicle nearing the box claims its connector, which is granted when it
is compatible (disjoint swept path, other source and target lanes) with every connector in use or granted
and the leaving lane has room for the vehicle; claimers are served longest-waiting first, and a waiting
claimer reserves its connector so that later, compatible streams cannot starve it. Without a grant the box
edge is a standing leader. A lane without successors ends the vehicle's trip: it respawns at the start of a
free road lane (MetaDrive respawns traffic the same way), or waits when none is free. A crosswalk whose
polygon (grown by `crosswalk_margin`) holds an agent or the ego becomes a standing leader at its near edge.
Where road lanes cross without a junction box, the crossing is a resource held by one axis at a time.

This module holds VehicleManager's reset, step and public API; its parts live beside it: lane routing and trip
ends (vehicle_routing), car following (vehicle_idm) and junction grants and lane crossings (vehicle_junctions).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon

from kernel.config import merge_strict
from sim.agents.lanes import (
    ConflictZones,
    Lane,
    build_conflict_zones,
    build_connectors,
    build_lanes,
    connector_compatibility,
)
from sim.agents.vehicle_idm import follow, idm, in_boxes, lane_points, leaders
from sim.agents.vehicle_junctions import JunctionControl
from sim.agents.vehicle_routing import LaneRouting
from sim.scene.scene import Scene, as_scene

__all__ = ["VEHICLE_DEFAULTS", "VEHICLE_DTYPE", "Lane", "VehicleManager", "build_lanes"]

VEHICLE_DTYPE = np.dtype(
    [("x", "f8"), ("y", "f8"), ("vx", "f8"), ("vy", "f8"), ("yaw", "f8"), ("length", "f8"), ("width", "f8")]
)

VEHICLE_DEFAULTS: dict[str, Any] = {
    "traffic_density": 1.0,  # vehicles per 100 m of lane (stochastic rounding per lane, so short lanes get some)
    "desired_speed": [8.0, 12.0],  # m/s (29-43 km/h, urban streets), drawn per vehicle
    "time_headway": 1.5,  # IDM T (s)
    "min_gap": 2.0,  # IDM s0 (m)
    "max_accel": 1.5,  # IDM a (m/s^2)
    "comfort_decel": 2.0,  # IDM b (m/s^2)
    "max_decel": 8.0,  # physical braking limit (m/s^2)
    "delta": 4.0,
    "length": 4.5,
    "width": 1.8,
    "crosswalk_margin": 1.0,  # agents this close to a crosswalk make vehicles yield
    "stop_gap": 1.5,  # where a yielding vehicle's front stops, before the crosswalk's near edge
    "max_hold": 10.0,  # s an axis may keep a lane crossing while vehicles of another axis wait
    "junction_stop": 1.0,  # m before the box edge where a vehicle without a grant stops
    "turn_accel": 3.0,  # m/s^2 lateral acceleration through turns: speed limit sqrt(a R) on connectors
    "turning": True,  # drive through X/T junctions on connectors (False: lanes end at the box, vehicles respawn)
}


class VehicleManager(LaneRouting, JunctionControl):
    """Vehicles driving the lanes of one scene with IDM, stopping for agents on crosswalks and at busy crossings."""

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = merge_strict(VEHICLE_DEFAULTS, config, name="vehicles config")
        self.n = 0
        self._scene: Scene | None = None

    def reset(self, scene: Scene | Mapping[str, Any], rng: np.random.Generator) -> np.ndarray:
        """Spawn `traffic_density` vehicles per 100 m of lane on `scene` (a dict is parsed), at least one IDM jam
        gap apart."""
        c = self.config
        self.rng = rng
        scene = as_scene(scene, self._scene)
        if scene is not self._scene:  # lanes, crossings and zones are pure functions of the scene: build once
            road = build_lanes(scene)
            self.n_road = len(road)
            self.lanes = road + (build_connectors(scene, road) if c["turning"] else [])
            self.is_connector = np.array([ln.is_connector for ln in self.lanes], dtype=bool)
            self.compatible = connector_compatibility(self.lanes, c["width"])
            self.crosswalks = [Polygon(cw["polygon"]).buffer(c["crosswalk_margin"]) for cw in scene.crosswalks]
            for cw in self.crosswalks:
                shapely.prepare(cw)
            self._cw_bounds = np.array([cw.bounds for cw in self.crosswalks]).reshape(-1, 4)
            self._cw_array = np.array(self.crosswalks, dtype=object)  # for one contains_xy call over all of them
            self.zones: ConflictZones = build_conflict_zones(road, c["width"])
            self._index_lanes()
            self._scene = scene
        lane_id, s = [], []
        spacing = c["length"] + c["min_gap"] + 2.0
        for li, lane in enumerate(self.lanes[: self.n_road]):  # nobody starts inside a junction box
            slots = np.arange(int(lane.length // spacing)) * spacing + 0.5 * c["length"]
            # No vehicle starts inside a lane crossing: two axes could otherwise begin inside one.
            z = self.zones.lane == li
            for lo, hi in zip(self.zones.s_in[z], self.zones.s_out[z]):
                slots = slots[(slots + c["length"] < lo) | (slots - c["length"] > hi)]
            want = c["traffic_density"] * lane.length / 100.0
            n = min(int(want) + int(rng.random() < want - int(want)), len(slots))
            if n <= 0:
                continue
            lane_id += [li] * n
            s += list(np.sort(rng.choice(slots, size=n, replace=False)) + rng.uniform(0.0, 1.0, n))
        self.lane_id = np.asarray(lane_id, dtype=np.int64)
        self.s = np.asarray(s, dtype=np.float64)
        self.n = len(self.s)
        lo, hi = c["desired_speed"]
        self.v0 = rng.uniform(lo, hi, self.n)
        self.v = self.v0 * rng.uniform(0.5, 1.0, self.n)
        self.occupied = np.zeros(len(self.crosswalks), dtype=bool)
        self.holder = np.full(self.zones.n_zones, np.nan)  # axis holding each crossing, nan when free
        self.held_for = np.zeros(self.zones.n_zones)
        self.respawns = self.continued = self.turns = 0
        self.jumped = np.zeros(self.n, dtype=bool)
        self.granted = np.zeros(self.n, dtype=bool)  # holds a grant for the junction connector it is heading to
        self.waited = np.zeros(self.n)  # s spent claiming a connector without a grant
        self.prev_lane = np.full(self.n, -1, dtype=np.int64)  # the lane a vehicle's rear may still be on
        self.next = np.array([self._draw_next(int(li)) for li in self.lane_id], dtype=np.int64)
        return self.states()

    def step(self, dt: float, people_xy: np.ndarray | None = None) -> np.ndarray:
        """Advance every vehicle by `dt` s; `people_xy` [n, 2] are agents and the ego (they make vehicles yield).
        Returns states()."""
        self.advance(dt, people_xy)
        return self.states()

    def advance(self, dt: float, people_xy: np.ndarray | None = None) -> None:
        """step() without building its states (the env reads `poses()`)."""
        c = self.config
        self.occupied = np.zeros(len(self.crosswalks), dtype=bool)
        if self.n and people_xy is not None and len(people_xy) and self.crosswalks:
            xy = np.ascontiguousarray(people_xy, dtype=np.float64)
            # Bounding boxes first: most ticks nobody is near a crosswalk and no polygon test runs at all.
            box, pt = in_boxes(xy, self._cw_bounds)
            if len(box):
                inside = shapely.contains_xy(self._cw_array[box], xy[pt, 0], xy[pt, 1])
                self.occupied[box[inside]] = True
        if self.n:
            order = np.lexsort((self.s, self.lane_id))
            cl, cc, cs = self._cross_arrays
            ls, ss, v, _, gap, dv, rear_s, rear_v, front, to_end, want = leaders(
                order,
                self.lane_id,
                self.s,
                self.v,
                self.next,
                self.lane_len,
                self.is_connector,
                self.granted,
                self.occupied,
                cl,
                cc,
                cs,
                float(c["length"]),
                float(c["stop_gap"]),
                float(dt),
                float(c["comfort_decel"]),
                float(c["junction_stop"]),
                len(self.lanes),
            )
            if self.zones.n_zones:
                self._crossing_leaders(dt, ls, ss, v, gap, dv)
            if want:  # a front vehicle nears a junction connector without a grant
                ids = order[front]
                self._grant(dt, ids, self.next[ids], to_end, v[front], rear_s)
            ratio = follow(
                order,
                ls,
                v,
                gap,
                dv,
                front,
                to_end,
                rear_s,
                rear_v,
                self.lane_id,
                self.s,
                self.v,
                self.v0,
                self.next,
                self.prev_lane,
                self.lane_len,
                self.vlim,
                self.is_connector,
                self.granted,
                self.occupied,
                cl,
                cc,
                cs,
                float(c["length"]),
                float(c["stop_gap"]),
                float(c["junction_stop"]),
                float(c["comfort_decel"]),
            )
            self.v, self.s = idm(
                order,
                v,
                gap,
                dv,
                ratio ** c["delta"],
                self.v,
                self.s,
                float(c["min_gap"]),
                float(c["time_headway"]),
                float(c["max_accel"]),
                float(c["comfort_decel"]),
                float(c["max_decel"]),
                float(dt),
            )
            self.jumped = np.zeros(self.n, dtype=bool)  # respawned this step (the only discontinuous moves)
            for i in np.flatnonzero(self.s >= self.lane_len[self.lane_id]).tolist():
                self._leave_lane(i)
            self.prev_lane[self.s >= c["length"]] = -1  # its rear has left the lane behind it

    def add(self, lane: int, s: float, speed: float = 0.0, next_lane: int | None = None) -> int:
        """Put one more vehicle on `lane` at arc length `s` (scripted scenarios); returns its index."""
        if not 0 <= lane < len(self.lanes):
            raise ValueError(f"lane {lane} does not exist; this scene has lanes 0..{len(self.lanes) - 1}")
        if next_lane is not None and next_lane not in self.successors[lane]:
            raise ValueError(
                f"lane {next_lane} does not follow lane {lane}; its successors are {self.successors[lane]}"
            )
        lo, hi = self.config["desired_speed"]
        self.lane_id = np.append(self.lane_id, lane)
        self.s = np.append(self.s, float(s))
        self.v0 = np.append(self.v0, 0.5 * (lo + hi))
        self.v = np.append(self.v, float(speed))
        self.jumped = np.append(self.jumped, False)
        self.granted = np.append(self.granted, False)
        self.waited = np.append(self.waited, 0.0)
        self.prev_lane = np.append(self.prev_lane, -1)
        self.next = np.append(self.next, self._draw_next(lane) if next_lane is None else next_lane)
        self.n += 1
        return self.n - 1

    def states(self) -> np.ndarray:
        """Every vehicle's centre, velocity, heading and size as a structured array of VEHICLE_DTYPE."""
        out = np.zeros(self.n, dtype=VEHICLE_DTYPE)
        if self.n:
            out["x"], out["y"], out["yaw"] = _, _, yaw = self.poses()
            out["vx"], out["vy"] = self.v * np.cos(yaw), self.v * np.sin(yaw)
        out["length"], out["width"] = self.config["length"], self.config["width"]
        return out

    def poses(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every vehicle's centre x, y and heading (the states' columns, without building the states)."""
        if not self.n:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        xy, seg = lane_points(self.lane_id, self.s, self.lane_off, self.lane_len, self.all_cum, self.all_pts)
        return xy[:, 0].copy(), xy[:, 1].copy(), np.arctan2(seg[:, 1], seg[:, 0])

    def fronts(self) -> tuple[np.ndarray, np.ndarray]:
        """(lane index, arc length of the front bumper) of every vehicle."""
        return self.lane_id.copy(), self.s + self.config["length"] / 2.0
