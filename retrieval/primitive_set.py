"""A labelled mesh set that is not procedural: street objects assembled by hand from trimesh primitives (boxes,
cylinders, cones, spheres) in two colours each, written as GLB files with sidecars (category, licence) into a
folder that the `local:` source reads. `curbside catalog eval --mesh-set primitives` scores it: the aligned scorer
never saw these shapes, so it measures how far training on the procedural library carries.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import cast

import numpy as np
import trimesh
from trimesh.creation import box, cone, cylinder, icosphere

RGB = {
    "gray": (128, 128, 132),
    "green": (40, 110, 50),
    "blue": (40, 70, 170),
    "red": (190, 30, 30),
    "yellow": (225, 190, 30),
    "orange": (240, 120, 20),
    "black": (30, 30, 30),
    "brown": (120, 80, 45),
    "white": (235, 235, 235),
    "silver": (185, 188, 192),
}


def _at(mesh: trimesh.Trimesh, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> trimesh.Trimesh:
    mesh.apply_translation([x, y, z])
    return mesh


def _cyl(r: float, h: float, z0: float = 0.0, x: float = 0.0, y: float = 0.0) -> trimesh.Trimesh:
    return _at(cylinder(radius=r, height=h, sections=24), x, y, z0 + h / 2)


def _box(dx: float, dy: float, dz: float, z0: float = 0.0, x: float = 0.0, y: float = 0.0) -> trimesh.Trimesh:
    return _at(box([dx, dy, dz]), x, y, z0 + dz / 2)


def _bench() -> list:
    legs = [_box(0.06, 0.06, 0.45, 0.0, sx * 0.2, sy * 0.8) for sx in (-1, 1) for sy in (-1, 1)]
    return [*legs, _box(0.45, 1.8, 0.06, 0.45), _box(0.06, 1.8, 0.45, 0.51, -0.2)]


def _trash_bin() -> list:
    return [_cyl(0.28, 0.85), _cyl(0.3, 0.06, 0.85)]


def _bollard() -> list:
    return [_cyl(0.1, 0.9), _at(icosphere(2, 0.1), z=0.9)]


def _street_lamp() -> list:
    return [_cyl(0.12, 0.4), _cyl(0.06, 6.0, 0.4), _box(0.9, 0.12, 0.08, 6.3, 0.4), _box(0.35, 0.25, 0.12, 6.18, 0.75)]


def _traffic_cone() -> list:
    return [_box(0.38, 0.38, 0.03), _at(cone(radius=0.15, height=0.7, sections=24), z=0.03)]


def _fire_hydrant() -> list:
    return [
        _cyl(0.16, 0.08),
        _cyl(0.12, 0.55, 0.08),
        _at(icosphere(2, 0.12), z=0.63),
        _at(
            cylinder(
                radius=0.05,
                height=0.36,
                sections=12,
                transform=trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]),
            ),
            z=0.45,
        ),
    ]


def _mailbox() -> list:
    return [
        _box(0.12, 0.12, 0.7),
        _box(0.5, 0.45, 0.5, 0.7),
        _at(
            cylinder(
                radius=0.225,
                height=0.5,
                sections=24,
                transform=trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0])
                @ trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1]),
            ),
            z=1.2,
        ),
    ]


def _tree() -> list:
    return [_cyl(0.15, 2.5), _at(icosphere(2, 1.6), z=3.6)]


def _drink_can() -> list:
    return [_cyl(0.033, 0.12)]


def _cardboard_box() -> list:
    return [_box(0.5, 0.4, 0.35)]


def _parking_meter() -> list:
    return [_cyl(0.04, 1.0), _box(0.2, 0.25, 0.4, 1.0)]


def _planter() -> list:
    return [_box(0.8, 0.8, 0.6), _at(icosphere(2, 0.45), z=0.85)]


# (builder, its two colours: the usual one first). The category is the builder's name, checked against the table.
SHAPES: tuple[tuple[Callable[[], list], tuple[str, str]], ...] = (
    (_bench, ("brown", "green")),
    (_trash_bin, ("gray", "green")),
    (_bollard, ("black", "yellow")),
    (_street_lamp, ("black", "gray")),
    (_traffic_cone, ("orange", "red")),
    (_fire_hydrant, ("red", "yellow")),
    (_mailbox, ("blue", "red")),
    (_tree, ("green", "green")),
    (_drink_can, ("red", "silver")),
    (_cardboard_box, ("brown", "white")),
    (_parking_meter, ("gray", "black")),
    (_planter, ("gray", "brown")),
)
FOLIAGE = (_tree, _planter)  # their last part is green foliage (a tree's trunk is brown)


def build_set(out: str | Path) -> list[Path]:
    """Write every shape in both colours as `<category>-<colour>.glb` + sidecar into `out`; returns the GLB paths."""
    import json

    from catalogs.categories import check_category

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for make, colours in SHAPES:
        cat = make.__name__.lstrip("_")
        check_category(cat, where="retrieval.primitive_set.SHAPES")
        for k, colour in enumerate(colours):
            parts = make()
            for n, part in enumerate(parts):
                rgb = (
                    RGB["green"]
                    if make in FOLIAGE and n == len(parts) - 1
                    else RGB["brown" if make is _tree else colour]
                )
                part.visual.face_colors = np.array([*rgb, 255], dtype=np.uint8)
            path = out / f"{cat}-{colour}-{k}.glb"
            mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(parts))  # Trimeshes concatenate to one
            path.write_bytes(cast(bytes, mesh.export(file_type="glb")))  # GLB is binary
            (out / f"{cat}-{colour}-{k}.json").write_text(
                json.dumps(
                    {"category": cat, "license": "CC0-1.0", "attribution": "curbside primitive set", "up_axis": "+z"}
                )
            )
            paths.append(path)
    return paths
