"""Low-poly figures for the cohabitants' visual shapes: people built from boxes and a sphere (legs, torso, arms,
head; a seat and wheels for wheelchair users, a deck for skateboarders and scooter riders, a frame and wheels for
cyclists), robots as their bodies. Collision and the LiDAR keep the kinds' capsules (sim/envs/bodies.py): the
figure is what cameras and the GUI draw. Figures face +x; the bodies turn them along the agent's motion."""

from __future__ import annotations

from typing import Any

from kernel.quiet import pybullet as p

Part = tuple[int, list[float], list[float], list[float]]  # (shape, half extents or [radius], frame position, rgba)
SKIN = [0.87, 0.72, 0.6, 1.0]
DARK = [0.15, 0.15, 0.18, 1.0]
METAL = [0.55, 0.57, 0.6, 1.0]


def _person(h: float, colour: list[float], z0: float) -> list[Part]:
    """A standing person of height `h` whose feet are at z0 (body frame), shirt in `colour`."""
    leg, torso, head = 0.47 * h, 0.3 * h, 0.07 * h
    hip = z0 + leg
    return [
        (p.GEOM_BOX, [0.07, 0.07, leg / 2], [0.0, 0.1, z0 + leg / 2], DARK),
        (p.GEOM_BOX, [0.07, 0.07, leg / 2], [0.0, -0.1, z0 + leg / 2], DARK),
        (p.GEOM_BOX, [0.1, 0.18, torso / 2], [0.0, 0.0, hip + torso / 2], colour),
        (p.GEOM_BOX, [0.05, 0.05, 0.16 * h], [0.0, 0.24, hip + torso - 0.16 * h], colour),
        (p.GEOM_BOX, [0.05, 0.05, 0.16 * h], [0.0, -0.24, hip + torso - 0.16 * h], colour),
        (p.GEOM_SPHERE, [head], [0.0, 0.0, hip + torso + 0.06 * h + head * 0.6], SKIN),
    ]


def figure_parts(kind: str, height: float, radius: float, colour: tuple[float, float, float]) -> list[Part]:
    """The parts of one kind's figure, in the body frame (origin at the body's centre, `height` tall)."""
    rgba = [*colour, 1.0]
    z0 = -height / 2
    if kind == "delivery_robot":
        return [
            (p.GEOM_BOX, [radius, 0.8 * radius, height / 2 - 0.05], [0.0, 0.0, 0.05], rgba),
            *[
                (p.GEOM_SPHERE, [0.07], [sx * 0.7 * radius, sy * 0.7 * radius, z0 + 0.07], DARK)
                for sx in (-1, 1)
                for sy in (-1, 1)
            ],
        ]
    if kind == "robot_dog":
        leg = 0.45 * height
        return [
            (p.GEOM_BOX, [radius, 0.4 * radius, 0.12], [0.0, 0.0, z0 + leg + 0.12], rgba),
            (p.GEOM_BOX, [0.09, 0.08, 0.07], [radius + 0.05, 0.0, z0 + leg + 0.2], DARK),
            *[
                (p.GEOM_BOX, [0.03, 0.03, leg / 2], [sx * 0.75 * radius, sy * 0.3 * radius, z0 + leg / 2], DARK)
                for sx in (-1, 1)
                for sy in (-1, 1)
            ],
        ]
    if kind == "wheelchair_user":
        seat = z0 + 0.5
        return [
            (p.GEOM_BOX, [0.25, 0.25, 0.04], [0.0, 0.0, seat], DARK),
            (p.GEOM_BOX, [0.04, 0.25, 0.25], [-0.25, 0.0, seat + 0.25], DARK),
            *[(p.GEOM_BOX, [0.3, 0.02, 0.3], [0.0, s * 0.3, z0 + 0.3], METAL) for s in (-1, 1)],
            (p.GEOM_BOX, [0.22, 0.16, 0.06], [0.12, 0.0, seat + 0.1], DARK),  # thighs
            (p.GEOM_BOX, [0.1, 0.18, 0.22], [-0.08, 0.0, seat + 0.3], rgba),
            (p.GEOM_SPHERE, [0.1], [-0.08, 0.0, seat + 0.62], SKIN),
        ]
    parts = _person(
        height if kind == "pedestrian" else 0.92 * height, rgba, z0 + (0.08 * height if kind != "pedestrian" else 0.0)
    )
    if kind in ("skateboarder", "scooter_rider"):
        parts.append((p.GEOM_BOX, [0.4, 0.1, 0.02], [0.0, 0.0, z0 + 0.06], METAL))
    if kind == "scooter_rider":
        parts.append((p.GEOM_BOX, [0.02, 0.02, 0.5], [0.38, 0.0, z0 + 0.55], METAL))
    if kind == "cyclist":
        parts += [(p.GEOM_BOX, [0.33, 0.02, 0.33], [s * 0.5, 0.0, z0 + 0.33], DARK) for s in (-1, 1)]
        parts.append((p.GEOM_BOX, [0.5, 0.03, 0.03], [0.0, 0.0, z0 + 0.6], METAL))
    return parts


def figure_shape(client: int, kind: str, height: float, radius: float, colour: tuple[float, float, float]) -> int:
    """A visual shape array of the kind's figure in `client`."""
    parts = figure_parts(kind, height, radius, colour)
    shapes = [s for s, _, _, _ in parts]
    kw: dict[str, Any] = {
        "halfExtents": [e if s == p.GEOM_BOX else [0, 0, 0] for s, e, _, _ in parts],
        "radii": [e[0] if s == p.GEOM_SPHERE else 0.0 for s, e, _, _ in parts],
        "visualFramePositions": [pos for _, _, pos, _ in parts],
        "rgbaColors": [c for _, _, _, c in parts],
    }
    return p.createVisualShapeArray(shapeTypes=shapes, physicsClientId=client, **kw)
