"""Vehicles: IDM keeps them on their lanes (on the road), apart, and stopped before occupied crosswalks."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon
from shapely.ops import unary_union

from sim.agents.vehicles import VEHICLE_DTYPE, VehicleManager
from sim.scene.grid import encode_walkable
from tests.street import NARROW
from tests.street import street as street_spec


@pytest.fixture(scope="module")
def street() -> dict:
    return street_spec(120.0, seed=0, crosswalks=(8.0, 112.0), **NARROW)


def test_vehicles_stay_on_roads_and_apart(street: dict) -> None:
    roads = unary_union([Polygon(r["polygon"]) for r in street["roads"]]).buffer(0.05)
    for seed in range(3):
        vm = VehicleManager({"traffic_density": 4.0})
        st = vm.reset(street, np.random.default_rng(seed))
        assert st.dtype == VEHICLE_DTYPE and vm.n >= 6
        for _ in range(500):
            st = vm.step(0.1)
            assert shapely.contains_xy(roads, st["x"], st["y"]).all()
            for li in np.unique(vm.state.lane_id):
                s = np.sort(vm.state.s[vm.state.lane_id == li])
                # Lanes are not rings: a vehicle at a lane's end leaves it, so only neighbours along it can touch.
                assert len(s) < 2 or (np.diff(s) - vm.config["length"]).min() > 0.0, "two vehicles in one lane overlap"
        assert np.mean(np.hypot(st["vx"], st["vy"])) > 3.0, "free traffic should be moving"


def test_vehicles_yield_at_occupied_crosswalk(street: dict) -> None:
    vm = VehicleManager({"traffic_density": 3.0})
    vm.reset(street, np.random.default_rng(1))
    person = np.array([[8.0, 0.5]])  # standing on crosswalk c0 (x in [6.5, 9.5])
    lanes, front = vm.fronts()
    s_in = {li: [s for ci, s, _ in vm.network.lanes[li].crossings if ci == 0][0] for li in range(len(vm.network.lanes))}
    # Only vehicles with room to brake comfortably are bound to stop; ones already at the line may go through.
    bound = np.array([s_in[li] - f > 30.0 for li, f in zip(lanes, front)])
    assert bound.any()
    for _ in range(300):
        vm.step(0.1, person)
        _, front = vm.fronts()
        # Arc lengths only wrap at the lane's end, which lies beyond the crosswalk for these vehicles.
        assert np.all(front[bound] < [s_in[li] for li in lanes[bound]])
    assert vm.state.occupied_crosswalks[0] and not vm.state.occupied_crosswalks[1]
    assert np.min(vm.state.speed) < 0.05, "the first vehicle in line should have stopped"
    for _ in range(150):
        vm.step(0.1, None)
    assert np.min(vm.state.speed) > 1.0, "vehicles should move on once the crosswalk is clear"


def _cross_spec(arm: float = 60.0, split: bool = False) -> dict:
    """Two one-lane-per-direction roads crossing at the origin (no intersection box: the lanes run through)."""

    def road(rid: str, line: list) -> dict:
        (x0, y0), (x1, y1) = line[0], line[-1]
        pad = 3.5
        poly = [
            [min(x0, x1) - pad * (x0 == x1), min(y0, y1) - pad * (y0 == y1)],
            [max(x0, x1) + pad * (x0 == x1), min(y0, y1) - pad * (y0 == y1)],
            [max(x0, x1) + pad * (x0 == x1), max(y0, y1) + pad * (y0 == y1)],
            [min(x0, x1) - pad * (x0 == x1), max(y0, y1) + pad * (y0 == y1)],
        ]
        return {"id": rid, "block": "X", "polygon": poly, "centerlines": [line], "lanes": 1, "lane_width": 3.5}

    xs = [[[-arm, 0.0], [0.0, 0.0]], [[0.0, 0.0], [arm, 0.0]]] if split else [[[-arm, 0.0], [arm, 0.0]]]
    roads = [road(f"h{k}", line) for k, line in enumerate(xs)] + [road("v", [[0.0, -arm], [0.0, arm]])]
    # A whole scene spec (VehicleManager parses it), with no sidewalk: only the roads matter here.
    return {
        "version": "curbside.scene/1",
        "seed": 0,
        "bounds": [-arm - 4.0, -arm - 4.0, arm + 4.0, arm + 4.0],
        "roads": roads,
        "sidewalks": [],
        "crosswalks": [],
        "objects": [],
        "walkable": encode_walkable(np.zeros((1, 1), dtype=np.uint8), (-arm, -arm), 1.0),
    }


def _boxes(st: np.ndarray) -> list[Polygon]:
    out = []
    for v in st:
        c, s = np.cos(v["yaw"]), np.sin(v["yaw"])
        corners = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * [v["length"] / 2, v["width"] / 2]
        out.append(Polygon(corners @ np.array([[c, s], [-s, c]]) + [v["x"], v["y"]]))
    return out


def test_crossing_traffic_takes_turns_and_never_overlaps() -> None:
    spec = _cross_spec()
    for seed in range(3):
        vm = VehicleManager({"traffic_density": 5.0})
        vm.reset(spec, np.random.default_rng(seed))
        assert vm.zones.n_zones == 1 and vm.n >= 8
        axes_through = set()
        for _ in range(600):
            st = vm.step(0.1)
            boxes = _boxes(st)
            tree = shapely.STRtree(boxes)
            a, b = tree.query(boxes, predicate="intersects")
            assert not np.any(a < b), f"seed {seed}: vehicles {a[a < b]} and {b[a < b]} overlap"
            if not np.isnan(vm.state.crossing_holder[0]):
                axes_through.add(round(abs(np.sin(vm.state.crossing_holder[0]))))
        assert axes_through == {0, 1}, "both roads should get the crossing in turn"
        assert vm.respawns > 0 and np.mean(vm.state.speed) > 1.0, "traffic should keep flowing through the crossing"


def test_vehicles_continue_onto_the_next_block_without_jumping() -> None:
    vm = VehicleManager({"traffic_density": 2.0})
    vm.reset(_cross_spec(split=True), np.random.default_rng(0))
    assert (vm.routing.continuation >= 0).sum() == 2, "each direction of the split road continues onto its other half"
    prev = vm.states()
    lane = vm.state.lane_id.copy()
    for _ in range(400):
        st = vm.step(0.1)
        moved = np.hypot(st["x"] - prev["x"], st["y"] - prev["y"])
        same = ((vm.state.lane_id == lane) | (vm.routing.continuation[lane] == vm.state.lane_id)) & ~vm.state.jumped
        # Staying on a lane or driving onto its continuation moves a vehicle by at most v dt; only respawns jump.
        assert np.all(moved[same] <= 0.1 * vm.config["desired_speed"][1] + 1e-6)
        prev, lane = st, vm.state.lane_id.copy()
    assert vm.continued > 0


@pytest.fixture(scope="module")
def junction() -> dict:
    import warnings

    from sim.scene import generate_scene

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # default-size boxes without a catalog
        return generate_scene({"blocks": "SXS", "crosswalk_density": 1.0}, 0)


def _right_turn(vm: VehicleManager) -> tuple[int, int, int, float]:
    """(source lane, connector, target lane, crosswalk index on the target) of a right turn into a crosswalk."""
    for ci in np.flatnonzero(vm.network.is_connector & vm.routing.is_turn).tolist():
        ln = vm.network.lanes[ci]
        d0, d1 = ln.points[1] - ln.points[0], ln.points[-1] - ln.points[-2]
        if d0[0] * d1[1] - d0[1] * d1[0] < 0 and vm.network.lanes[ln.dst].crossings:  # clockwise: a right turn
            return ln.src, ci, ln.dst, vm.network.lanes[ln.dst].crossings[0][0]
    raise AssertionError("the X block has no right turn onto a lane with a crosswalk")


def test_a_vehicle_turns_at_an_intersection_and_stops_for_a_pedestrian_on_the_crosswalk(junction: dict) -> None:
    def drive(person: np.ndarray | None) -> tuple[VehicleManager, list[tuple[int, float, float]]]:
        vm = VehicleManager({"traffic_density": 0.0})
        vm.reset(junction, np.random.default_rng(0))
        src, conn, dst, _ = _right_turn(vm)
        i = vm.add(src, vm.network.lanes[src].length - 40.0, speed=8.0, next_lane=conn)
        trace = []
        for _ in range(250):
            st = vm.step(0.1, person)
            trace.append((int(vm.state.lane_id[i]), float(vm.state.s[i]), float(st["yaw"][i])))
        return vm, trace

    vm, trace = drive(None)
    src, conn, dst, cw = _right_turn(vm)
    lanes = [t[0] for t in trace]
    assert conn in lanes and dst in lanes, "the vehicle should drive through the connector onto the target lane"
    turned = np.angle(np.exp(1j * (trace[-1][2] - trace[0][2])))
    assert turned < -np.radians(60), (
        f"a right turn should change the heading by about -90 degrees, got {np.degrees(turned):.0f}"
    )
    assert vm.turns >= 1

    poly = vm.crosswalks.polygons[cw]
    person = np.array([[poly.centroid.x, poly.centroid.y]])  # someone standing on the target lane's crosswalk
    vm, trace = drive(person)
    s_in = [s for c, s, _ in vm.network.lanes[dst].crossings if c == cw][0]
    half = vm.config["length"] / 2.0
    # Never past the crosswalk's near edge, and stopped there, after turning into the box.
    assert all(lane != dst or s + half < s_in for lane, s, _ in trace), "the vehicle drove onto the occupied crosswalk"
    assert trace[-1][0] in (conn, dst) and vm.state.speed[-1] < 0.05
    passed = False
    for _ in range(100):
        vm.step(0.1, None)
        passed |= bool(vm.state.lane_id[-1] == dst and vm.state.s[-1] - half > s_in)
    assert passed, "with the crosswalk clear the vehicle drives on over it"


@pytest.mark.parametrize("blocks", ["SXS", "STS"])
def test_junction_traffic_turns_and_never_overlaps(blocks: str) -> None:
    import warnings

    from sim.scene import generate_scene

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        spec = generate_scene({"blocks": blocks, "crosswalk_density": 0.0}, 1)
    roads = unary_union([Polygon(r["polygon"]) for r in spec["roads"]]).buffer(0.3)
    vm = VehicleManager({"traffic_density": 2.0})
    vm.reset(spec, np.random.default_rng(0))
    assert vm.network.is_connector.any()
    for k in range(1200):
        st = vm.step(0.1)
        assert shapely.contains_xy(roads, st["x"], st["y"]).all(), "a vehicle left the roads"
        if k % 3 == 0:
            boxes = _boxes(st)
            a, b = shapely.STRtree(boxes).query(boxes, predicate="intersects")
            assert not np.any(a < b), f"step {k}: vehicles {a[a < b]} and {b[a < b]} overlap"
    assert vm.turns >= 5, "vehicles should turn left and right through the junction"
    assert np.mean(vm.state.speed) > 1.0 and vm.continued > 0
