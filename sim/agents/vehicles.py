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

VehicleManager composes small parts that take their inputs explicitly: the scene's LaneNetwork and the episode's
TrafficState (vehicle_state), lane routing and trip ends (vehicle_routing.LaneRouting), car following
(vehicle_idm's numba kernels), and junction grants, lane crossings and crosswalk occupancy (vehicle_junctions).
It builds the scene's parts once per scene, spawns the episode's vehicles into a new TrafficState at reset and
runs the parts in order every step.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from kernel.config import merge_strict
from sim.agents.lanes import (
    ConflictZones,
    Lane,
    build_conflict_zones,
    build_connectors,
    build_lanes,
    connector_compatibility,
)
from sim.agents.vehicle_config import VEHICLE_DEFAULTS, VEHICLES_TABLE
from sim.agents.vehicle_idm import follow, idm, leaders
from sim.agents.vehicle_junctions import CrosswalkOccupancy, JunctionGrants, LaneCrossings
from sim.agents.vehicle_routing import LaneRouting
from sim.agents.vehicle_state import LaneNetwork, TrafficState
from sim.scene.scene import Scene, as_scene
from sim.schema import check_table

__all__ = ["VEHICLE_DEFAULTS", "VEHICLE_DTYPE", "Lane", "TrafficState", "VehicleManager", "build_lanes"]

VEHICLE_DTYPE = np.dtype(
    [("x", "f8"), ("y", "f8"), ("vx", "f8"), ("vy", "f8"), ("yaw", "f8"), ("length", "f8"), ("width", "f8")]
)


class VehicleManager:
    """Vehicles driving the lanes of one scene with IDM, stopping for agents on crosswalks and at busy crossings.

    `state` is the episode's TrafficState; `network`, `zones`, `crosswalks`, `routing`, `junctions` and `crossings`
    are the scene's lane network, lane crossings, crosswalks and parts, built by reset() for its scene.
    """

    network: LaneNetwork
    zones: ConflictZones
    crosswalks: CrosswalkOccupancy
    routing: LaneRouting
    junctions: JunctionGrants
    crossings: LaneCrossings
    _rng: np.random.Generator  # the episode's generator (next lanes, respawn lanes), passed to reset()

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = merge_strict(VEHICLE_DEFAULTS, config, name="vehicles config")
        check_table(self.config, VEHICLES_TABLE, name="vehicles config")
        self.state = TrafficState.empty()
        self._scene: Scene | None = None

    @property
    def n(self) -> int:
        """Number of vehicles."""
        return self.state.n

    @property
    def respawns(self) -> int:
        """Trips ended and started again at a free lane start this episode."""
        return self.state.respawns

    @property
    def continued(self) -> int:
        """Road lanes left onto the road lane continuing them this episode."""
        return self.state.continued

    @property
    def turns(self) -> int:
        """Junction connectors entered this episode that turn by more than 45 degrees."""
        return self.state.turns

    def _build_scene(self, scene: Scene) -> None:
        """The scene's lanes, crossings, crosswalks and the parts that use them (pure functions of the scene)."""
        cfg = self.config
        road = build_lanes(scene)
        lanes = road + (build_connectors(scene, road) if cfg["turning"] else [])
        self.network = LaneNetwork.build(lanes, len(road), cfg["turn_accel"])
        self.zones = build_conflict_zones(road, cfg["width"])
        self.crosswalks = CrosswalkOccupancy(scene.crosswalks, cfg["crosswalk_margin"])
        self.routing = LaneRouting(self.network, self.zones, cfg["length"], cfg["min_gap"], cfg["time_headway"])
        compatible = connector_compatibility(lanes, cfg["width"])
        self.junctions = JunctionGrants(
            self.network, compatible, cfg["length"], cfg["min_gap"], cfg["comfort_decel"], cfg["junction_stop"]
        )
        self.crossings = LaneCrossings(
            self.zones, cfg["length"], cfg["stop_gap"], cfg["comfort_decel"], cfg["max_hold"]
        )
        self._scene = scene

    def reset(self, scene: Scene | Mapping[str, Any], rng: np.random.Generator) -> np.ndarray:
        """Spawn `traffic_density` vehicles per 100 m of lane on `scene` (a dict is parsed), at least one IDM jam
        gap apart."""
        cfg = self.config
        self._rng = rng
        scene = as_scene(scene, self._scene)
        if scene is not self._scene:  # lanes, crossings and zones are pure functions of the scene: build once
            self._build_scene(scene)
        z = self.zones
        lane_id, s = [], []
        spacing = cfg["length"] + cfg["min_gap"] + 2.0
        for li, lane in enumerate(self.network.lanes[: self.network.n_road]):  # nobody starts inside a junction box
            slots = np.arange(int(lane.length // spacing)) * spacing + 0.5 * cfg["length"]
            # No vehicle starts inside a lane crossing: two axes could otherwise begin inside one.
            on = z.lane == li
            for lo, hi in zip(z.s_in[on], z.s_out[on]):
                slots = slots[(slots + cfg["length"] < lo) | (slots - cfg["length"] > hi)]
            want = cfg["traffic_density"] * lane.length / 100.0
            count = min(int(want) + int(rng.random() < want - int(want)), len(slots))
            if count <= 0:
                continue
            lane_id += [li] * count
            s += list(np.sort(rng.choice(slots, size=count, replace=False)) + rng.uniform(0.0, 1.0, count))
        count = len(s)
        lo, hi = cfg["desired_speed"]
        desired_speed = rng.uniform(lo, hi, count)
        speed = desired_speed * rng.uniform(0.5, 1.0, count)
        self.state = TrafficState(
            lane_id=np.asarray(lane_id, dtype=np.int64),
            s=np.asarray(s, dtype=np.float64),
            speed=speed,
            desired_speed=desired_speed,
            next_lane=np.array([self.routing.draw_next(li, rng) for li in lane_id], dtype=np.int64),
            prev_lane=np.full(count, -1, dtype=np.int64),
            granted=np.zeros(count, dtype=bool),
            waited=np.zeros(count),
            jumped=np.zeros(count, dtype=bool),
            occupied_crosswalks=np.zeros(len(self.crosswalks.polygons), dtype=bool),
            crossing_holder=np.full(z.n_zones, np.nan),
            crossing_held_for=np.zeros(z.n_zones),
        )
        return self.states()

    def clear(self) -> None:
        """Remove every vehicle (an episode without traffic)."""
        self.state = TrafficState.empty()

    def step(self, dt: float, people_xy: np.ndarray | None = None) -> np.ndarray:
        """Advance every vehicle by `dt` s; `people_xy` [n, 2] are agents and the ego (they make vehicles yield).
        Returns states()."""
        self.advance(dt, people_xy)
        return self.states()

    def advance(self, dt: float, people_xy: np.ndarray | None = None) -> None:
        """step() without building its states (the env reads `poses()`)."""
        cfg, st, net = self.config, self.state, self.network
        st.occupied_crosswalks = self.crosswalks.occupied(people_xy if st.n else None)
        if not st.n:
            return
        order = np.lexsort((st.s, st.lane_id))
        cl, cc, cs = net.crosswalk_lane, net.crosswalk_index, net.crosswalk_s
        ls, ss, v, _, gap, dv, rear_s, rear_v, front, to_end, want = leaders(
            order,
            st.lane_id,
            st.s,
            st.speed,
            st.next_lane,
            net.lane_len,
            net.is_connector,
            st.granted,
            st.occupied_crosswalks,
            cl,
            cc,
            cs,
            float(cfg["length"]),
            float(cfg["stop_gap"]),
            float(dt),
            float(cfg["comfort_decel"]),
            float(cfg["junction_stop"]),
            len(net.lanes),
        )
        self.crossings.take_turns(st, dt, ls, ss, v, gap, dv)
        if want:  # a front vehicle nears a junction connector without a grant
            ids = order[front]
            self.junctions.grant(st, dt, ids, st.next_lane[ids], to_end, v[front], rear_s)
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
            st.lane_id,
            st.s,
            st.speed,
            st.desired_speed,
            st.next_lane,
            st.prev_lane,
            net.lane_len,
            net.speed_limit,
            net.is_connector,
            st.granted,
            st.occupied_crosswalks,
            cl,
            cc,
            cs,
            float(cfg["length"]),
            float(cfg["stop_gap"]),
            float(cfg["junction_stop"]),
            float(cfg["comfort_decel"]),
        )
        st.speed, st.s = idm(
            order,
            v,
            gap,
            dv,
            ratio ** cfg["delta"],
            st.speed,
            st.s,
            float(cfg["min_gap"]),
            float(cfg["time_headway"]),
            float(cfg["max_accel"]),
            float(cfg["comfort_decel"]),
            float(cfg["max_decel"]),
            float(dt),
        )
        st.jumped = np.zeros(st.n, dtype=bool)
        for i in np.flatnonzero(st.s >= net.lane_len[st.lane_id]).tolist():
            self.routing.leave_lane(st, i, self._rng)
        st.prev_lane[st.s >= cfg["length"]] = -1  # its rear has left the lane behind it

    def add(self, lane: int, s: float, speed: float = 0.0, next_lane: int | None = None) -> int:
        """Put one more vehicle on `lane` at arc length `s` (scripted scenarios); returns its index."""
        n_lanes, successors = len(self.network.lanes), self.routing.successors
        if not 0 <= lane < n_lanes:
            raise ValueError(f"lane {lane} does not exist; this scene has lanes 0..{n_lanes - 1}")
        if next_lane is not None and next_lane not in successors[lane]:
            raise ValueError(f"lane {next_lane} does not follow lane {lane}; its successors are {successors[lane]}")
        lo, hi = self.config["desired_speed"]
        nxt = self.routing.draw_next(lane, self._rng) if next_lane is None else next_lane
        return self.state.append(lane, s, speed, 0.5 * (lo + hi), nxt)

    def states(self) -> np.ndarray:
        """Every vehicle's centre, velocity, heading and size as a structured array of VEHICLE_DTYPE."""
        out = np.zeros(self.n, dtype=VEHICLE_DTYPE)
        if self.n:
            out["x"], out["y"], out["yaw"] = _, _, yaw = self.poses()
            out["vx"], out["vy"] = self.state.speed * np.cos(yaw), self.state.speed * np.sin(yaw)
        out["length"], out["width"] = self.config["length"], self.config["width"]
        return out

    def poses(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every vehicle's centre x, y and heading (the states' columns, without building the states)."""
        if not self.n:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        xy, seg = self.network.points(self.state.lane_id, self.state.s)
        return xy[:, 0].copy(), xy[:, 1].copy(), np.arctan2(seg[:, 1], seg[:, 0])

    def fronts(self) -> tuple[np.ndarray, np.ndarray]:
        """(lane index, arc length of the front bumper) of every vehicle."""
        return self.state.lane_id.copy(), self.state.s + self.config["length"] / 2.0
