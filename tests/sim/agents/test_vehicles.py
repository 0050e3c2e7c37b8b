"""Vehicles: IDM keeps them on their lanes (on the road), apart, and stopped before occupied crosswalks."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon
from shapely.ops import unary_union

from sim.agents import toy_street_spec
from sim.agents.vehicles import VEHICLE_DTYPE, VehicleManager


@pytest.fixture(scope="module")
def street() -> dict:
    return toy_street_spec(length=120.0, seed=0)


def test_vehicles_stay_on_roads_and_apart(street: dict) -> None:
    roads = unary_union([Polygon(r["polygon"]) for r in street["roads"]]).buffer(0.05)
    for seed in range(3):
        vm = VehicleManager({"traffic_density": 4.0})
        st = vm.reset(street, np.random.default_rng(seed))
        assert st.dtype == VEHICLE_DTYPE and vm.n >= 6
        for _ in range(500):
            st = vm.step(0.1)
            assert shapely.contains_xy(roads, st["x"], st["y"]).all()
            for li in np.unique(vm.lane_id):
                s = np.sort(vm.s[vm.lane_id == li])
                gaps = np.diff(np.concatenate([s, [s[0] + vm.lanes[li].length]])) - vm.config["length"]
                assert gaps.min() > 0.0, "two vehicles in one lane overlap"
        assert np.mean(np.hypot(st["vx"], st["vy"])) > 3.0, "free traffic should be moving"


def test_vehicles_yield_at_occupied_crosswalk(street: dict) -> None:
    vm = VehicleManager({"traffic_density": 3.0})
    vm.reset(street, np.random.default_rng(1))
    person = np.array([[8.0, 0.5]])  # standing on crosswalk c0 (x in [6.5, 9.5])
    lanes, front = vm.fronts()
    s_in = {li: [s for ci, s, _ in vm.lanes[li].crossings if ci == 0][0] for li in range(len(vm.lanes))}
    # Only vehicles with room to brake comfortably are bound to stop; ones already at the line may go through.
    bound = np.array([s_in[li] - f > 30.0 for li, f in zip(lanes, front)])
    assert bound.any()
    for _ in range(300):
        vm.step(0.1, person)
        _, front = vm.fronts()
        # Arc lengths only wrap at the lane's end, which lies beyond the crosswalk for these vehicles.
        assert np.all(front[bound] < [s_in[li] for li in lanes[bound]])
    assert vm.occupied[0] and not vm.occupied[1]
    assert np.min(vm.v) < 0.05, "the first vehicle in line should have stopped"
    for _ in range(150):
        vm.step(0.1, None)
    assert np.min(vm.v) > 1.0, "vehicles should move on once the crosswalk is clear"
