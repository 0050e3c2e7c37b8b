"""The vehicles' configuration (SocialNav's `vehicles`): one Key per setting, VEHICLE_DEFAULTS and VEHICLES_TABLE."""

from __future__ import annotations

from typing import Any

from sim.schema import Bool, Float, Key, Pair, Pos, Rule, Table, defaults_of, table_of

VEHICLE_KEYS: dict[str, Key] = {
    "traffic_density": Key(
        1.0,
        Float(0.0, 100.0, hint="vehicles per 100 m of lane"),
        "vehicles per 100 m of lane (stochastic rounding per lane, so short lanes get some)",
    ),
    "desired_speed": Key(
        [8.0, 12.0], Pair(Float(0.0, 50.0), hint="m/s"), "m/s (29-43 km/h, urban streets), drawn per vehicle"
    ),
    "time_headway": Key(1.5, Pos(100.0), "IDM T (s)"),
    "min_gap": Key(2.0, Float(0.0, 100.0), "IDM s0 (m)"),
    "max_accel": Key(1.5, Pos(100.0), "IDM a (m/s^2)"),
    "comfort_decel": Key(2.0, Pos(100.0), "IDM b (m/s^2)"),
    "max_decel": Key(8.0, Pos(100.0), "physical braking limit (m/s^2)"),
    "delta": Key(4.0, Pos(100.0), "IDM acceleration exponent"),
    "length": Key(4.5, Pos(50.0), "vehicle length (m)"),
    "width": Key(1.8, Pos(20.0), "vehicle width (m)"),
    "crosswalk_margin": Key(1.0, Float(0.0, 100.0), "agents this close to a crosswalk make vehicles yield"),
    "stop_gap": Key(1.5, Float(0.0, 100.0), "where a yielding vehicle's front stops, before the crosswalk's near edge"),
    "max_hold": Key(10.0, Pos(3600.0), "s an axis may keep a lane crossing while vehicles of another axis wait"),
    "junction_stop": Key(1.0, Float(0.0, 100.0), "m before the box edge where a vehicle without a grant stops"),
    # Positive: the connectors' speed limits are square roots of it.
    "turn_accel": Key(3.0, Pos(100.0), "m/s^2 lateral acceleration through turns: speed limit sqrt(a R) on connectors"),
    "turning": Key(
        True, Bool(), "drive through X/T junctions on connectors (False: lanes end at the box, vehicles respawn)"
    ),
}
VEHICLE_DEFAULTS: dict[str, Any] = defaults_of(VEHICLE_KEYS)
VEHICLES_TABLE: dict[str, Rule | Table] = table_of(VEHICLE_KEYS)
