"""What the vehicle parts share: the scene's lane network, indexed once per scene, and the episode's traffic state.

VehicleManager builds both and passes them to its parts (vehicle_routing, vehicle_junctions) and to the car
following kernels (vehicle_idm); every per-vehicle array of TrafficState has one entry per vehicle, in the same
order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.agents.lanes import Lane
from sim.agents.vehicle_idm import lane_points


@dataclass(frozen=True)
class LaneNetwork:
    """The scene's lanes, indexed for the kernels: road lanes first, then junction connectors, laid end to end (1 m
    apart) in one point array so that poses and leaders are found for every vehicle at once."""

    lanes: list[Lane]  # road lanes (indices below n_road), then the junction connectors
    n_road: int  # how many of `lanes` are road lanes
    is_connector: np.ndarray  # bool [lanes]: the lane is a path through a junction box
    lane_len: np.ndarray  # float [lanes]: each lane's length (m)
    lane_start: np.ndarray  # float [lanes]: where each lane starts in the end-to-end layout
    layout_points: np.ndarray  # float [points, 2]: every lane's points, lane after lane
    layout_s: np.ndarray  # float [points]: the layout's arc length at each of those points
    crosswalk_lane: np.ndarray  # int64 [entries]: per crosswalk a lane crosses, that lane ...
    crosswalk_index: np.ndarray  # int64 [entries]: ... the crosswalk ...
    crosswalk_s: np.ndarray  # float [entries]: ... and the arc length of the crosswalk's near edge along the lane
    speed_limit: np.ndarray  # float [lanes]: sqrt(turn_accel * smallest radius) on connectors, inf on road lanes

    @classmethod
    def build(cls, lanes: list[Lane], n_road: int, turn_accel: float) -> LaneNetwork:
        """Index `lanes` (the first `n_road` road lanes, the rest connectors) with `turn_accel` (m/s^2) the lateral
        acceleration that sets each connector's speed limit."""
        lane_len = np.array([ln.length for ln in lanes])
        lane_start = np.concatenate([[0.0], np.cumsum(lane_len + 1.0)])[:-1]
        entries = [(li, ci, s_in) for li, ln in enumerate(lanes) for ci, s_in, _ in ln.crossings]
        is_connector = np.array([ln.is_connector for ln in lanes], dtype=bool)
        speed_limit = np.full(len(lanes), np.inf)
        for ci in np.flatnonzero(is_connector).tolist():
            speed_limit[ci] = np.sqrt(turn_accel * _min_radius(lanes[ci].points))
        return cls(
            lanes=lanes,
            n_road=n_road,
            is_connector=is_connector,
            lane_len=lane_len,
            lane_start=lane_start,
            layout_points=np.concatenate([ln.points for ln in lanes]) if lanes else np.zeros((0, 2)),
            layout_s=np.concatenate([ln.s + o for ln, o in zip(lanes, lane_start)]) if lanes else np.zeros(0),
            crosswalk_lane=np.array([x[0] for x in entries], dtype=np.int64),
            crosswalk_index=np.array([x[1] for x in entries], dtype=np.int64),
            crosswalk_s=np.array([x[2] for x in entries], dtype=np.float64),
            speed_limit=speed_limit,
        )

    def points(self, lane_id: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres [n, 2] of vehicles at arc lengths `s` on lanes `lane_id`, and the direction [n, 2] of the lane
        segment each is on."""
        return lane_points(lane_id, s, self.lane_start, self.lane_len, self.layout_s, self.layout_points)


@dataclass
class TrafficState:
    """The vehicles of one episode (one entry per vehicle in each per-vehicle array), the right of way at the lane
    crossings and the episode's counters."""

    lane_id: np.ndarray  # int64 [n]: the lane each vehicle drives on
    s: np.ndarray  # float [n]: arc length of its centre along that lane (m)
    speed: np.ndarray  # float [n]: its speed (m/s)
    desired_speed: np.ndarray  # float [n]: IDM's v0, its speed on a free road (m/s)
    next_lane: np.ndarray  # int64 [n]: the lane it drives onto after this one, -1 where its trip ends
    prev_lane: np.ndarray  # int64 [n]: the lane its rear may still be on, -1 once it has left it
    granted: np.ndarray  # bool [n]: it holds a grant for the junction connector it is heading to
    waited: np.ndarray  # float [n]: seconds spent claiming a junction connector without a grant
    jumped: np.ndarray  # bool [n]: respawned in the last step (the only discontinuous moves)
    occupied_crosswalks: np.ndarray  # bool [crosswalks]: someone stood inside the (grown) crosswalk last step
    crossing_holder: np.ndarray  # float [zones]: axis (radians) holding each lane crossing, nan when free
    crossing_held_for: np.ndarray  # float [zones]: seconds the holding axis has held each lane crossing
    respawns: int = 0  # trips ended and started again at a free lane start
    continued: int = 0  # road lanes left onto the road lane continuing them
    turns: int = 0  # junction connectors entered that turn by more than 45 degrees

    @classmethod
    def empty(cls, n_crosswalks: int = 0, n_zones: int = 0) -> TrafficState:
        """No vehicles, free crosswalks and lane crossings."""
        return cls(
            lane_id=np.zeros(0, dtype=np.int64),
            s=np.zeros(0),
            speed=np.zeros(0),
            desired_speed=np.zeros(0),
            next_lane=np.zeros(0, dtype=np.int64),
            prev_lane=np.zeros(0, dtype=np.int64),
            granted=np.zeros(0, dtype=bool),
            waited=np.zeros(0),
            jumped=np.zeros(0, dtype=bool),
            occupied_crosswalks=np.zeros(n_crosswalks, dtype=bool),
            crossing_holder=np.full(n_zones, np.nan),
            crossing_held_for=np.zeros(n_zones),
        )

    @property
    def n(self) -> int:
        """Number of vehicles."""
        return len(self.s)

    def append(self, lane: int, s: float, speed: float, desired_speed: float, next_lane: int) -> int:
        """Add one vehicle, without a grant, claim, respawn or lane behind it; returns its index."""
        self.lane_id = np.append(self.lane_id, lane)
        self.s = np.append(self.s, float(s))
        self.desired_speed = np.append(self.desired_speed, desired_speed)
        self.speed = np.append(self.speed, float(speed))
        self.jumped = np.append(self.jumped, False)
        self.granted = np.append(self.granted, False)
        self.waited = np.append(self.waited, 0.0)
        self.prev_lane = np.append(self.prev_lane, -1)
        self.next_lane = np.append(self.next_lane, next_lane)
        return self.n - 1


def _min_radius(pts: np.ndarray) -> float:
    """Smallest radius of the circles through consecutive point triples of a polyline (inf when straight)."""
    a, b, c = pts[:-2], pts[1:-1], pts[2:]
    ab, bc, ca = (np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1))
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = ab * bc * ca / (2.0 * cross)
    r = r[np.isfinite(r)]
    return float(r.min()) if len(r) else float("inf")
