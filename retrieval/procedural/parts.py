"""Shared helpers of the generators: a coloured-part builder over trimesh primitives and a seeded sampling context."""

from __future__ import annotations

from itertools import pairwise
from typing import Any, cast

import numpy as np
import trimesh

from retrieval.procedural.spec import CategorySpec, Variant, hex_to_rgba

RGBA = tuple[int, int, int, int]

# Accent colours shared by several categories (the body colour comes from the sampled variant).
DARK = "#2b2b2b"
BLACK = "#141414"
RUBBER = "#1a1a1a"
WHITE = "#f2f2f2"
METAL = "#8a8d91"
STEEL = "#b9bdc1"
GLASS = "#5f7f96"
LIGHT = "#fff2b8"
CONCRETE = "#a7a39b"
WOOD = "#8b5a2b"
BARK = "#5b4030"
FOLIAGE = "#3f7d3a"
SOIL = "#4a3525"


def rgba(color: str | RGBA) -> RGBA:
    """Normalise a '#rrggbb' string or an RGBA tuple to an RGBA tuple of ints."""
    if isinstance(color, str):
        return hex_to_rgba(color)
    return tuple(int(c) for c in color)  # type: ignore[return-value]


def _placed(mesh: trimesh.Trimesh, center: tuple[float, float, float]) -> trimesh.Trimesh:
    mesh.apply_translation(np.asarray(center, dtype=float))
    return mesh


class Parts:
    """Collects coloured primitive parts; every method takes metres and a colour and places one part."""

    def __init__(self) -> None:
        self._meshes: list[trimesh.Trimesh] = []
        self._colors: list[RGBA] = []

    def add(self, mesh: trimesh.Trimesh, color: str | RGBA) -> trimesh.Trimesh:
        """Add an already placed mesh with one colour."""
        self._meshes.append(mesh)
        self._colors.append(rgba(color))
        return mesh

    def box(
        self,
        size: tuple[float, float, float],
        center: tuple[float, float, float],
        color: str | RGBA,
        rot_x: float = 0.0,
        rot_y: float = 0.0,
    ) -> trimesh.Trimesh:
        """Axis-aligned box of extents `size` (x, y, z) at `center`, optionally rotated about x then y (radians)."""
        m = trimesh.creation.box(extents=np.maximum(np.asarray(size, dtype=float), 1e-4))
        if rot_x:
            m.apply_transform(trimesh.transformations.rotation_matrix(rot_x, [1, 0, 0]))
        if rot_y:
            m.apply_transform(trimesh.transformations.rotation_matrix(rot_y, [0, 1, 0]))
        return self.add(_placed(m, center), color)

    def slab(
        self, x: tuple[float, float], y: tuple[float, float], z: tuple[float, float], color: str | RGBA
    ) -> trimesh.Trimesh:
        """Box spanning the intervals x, y, z (min, max); the easiest way to lay out furniture."""
        size = (x[1] - x[0], y[1] - y[0], z[1] - z[0])
        center = ((x[0] + x[1]) / 2, (y[0] + y[1]) / 2, (z[0] + z[1]) / 2)
        return self.box(size, center, color)

    def frustum(
        self,
        r_bottom: float,
        r_top: float,
        z0: float,
        z1: float,
        color: str | RGBA,
        xy: tuple[float, float] = (0.0, 0.0),
        sections: int = 24,
        rot_z: float = 0.0,
    ) -> trimesh.Trimesh:
        """Vertical truncated cone (a cylinder when the radii match) from height z0 to z1."""
        m = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=sections)
        v = m.vertices.copy()
        top = v[:, 2] > 0
        v[:, :2] *= np.where(top, r_top, r_bottom)[:, None]
        v[:, 2] = np.where(top, z1, z0)
        m = trimesh.Trimesh(vertices=v, faces=m.faces, process=False)
        if rot_z:
            m.apply_transform(trimesh.transformations.rotation_matrix(rot_z, [0, 0, 1]))
        return self.add(_placed(m, (xy[0], xy[1], 0.0)), color)

    def cylinder(
        self,
        radius: float,
        z0: float,
        z1: float,
        color: str | RGBA,
        xy: tuple[float, float] = (0.0, 0.0),
        sections: int = 24,
    ) -> trimesh.Trimesh:
        """Vertical cylinder from height z0 to z1 centred at `xy`."""
        return self.frustum(radius, radius, z0, z1, color, xy, sections)

    def rod(
        self,
        p0: tuple[float, float, float],
        p1: tuple[float, float, float],
        radius: float,
        color: str | RGBA,
        sections: int = 12,
    ) -> trimesh.Trimesh:
        """Cylinder between two points (tubes, arms, axles)."""
        m = trimesh.creation.cylinder(radius=radius, sections=sections, segment=np.array([p0, p1], dtype=float))
        return self.add(m, color)

    def sphere(
        self,
        radii: float | tuple[float, float, float],
        center: tuple[float, float, float],
        color: str | RGBA,
        subdivisions: int = 2,
    ) -> trimesh.Trimesh:
        """Icosphere, or an ellipsoid when `radii` is a triple."""
        m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
        m.apply_scale(np.broadcast_to(np.asarray(radii, dtype=float), (3,)))
        return self.add(_placed(m, center), color)

    def cone(
        self,
        radius: float,
        z0: float,
        z1: float,
        color: str | RGBA,
        xy: tuple[float, float] = (0.0, 0.0),
        sections: int = 24,
    ) -> trimesh.Trimesh:
        """Pointed vertical cone with its base at z0 and tip at z1."""
        m = trimesh.creation.cone(radius=radius, height=z1 - z0, sections=sections)
        return self.add(_placed(m, (xy[0], xy[1], z0)), color)

    def torus(
        self,
        major: float,
        minor: float,
        center: tuple[float, float, float],
        color: str | RGBA,
        axis: str = "y",
        sections: int = 32,
    ) -> trimesh.Trimesh:
        """Ring (wheel, tyre) around `axis` ('x', 'y' or 'z')."""
        m = trimesh.creation.torus(major_radius=major, minor_radius=minor, major_sections=sections, minor_sections=8)
        if axis == "y":
            m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
        elif axis == "x":
            m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
        return self.add(_placed(m, center), color)

    def capsule(
        self, radius: float, p0: tuple[float, float, float], p1: tuple[float, float, float], color: str | RGBA
    ) -> trimesh.Trimesh:
        """Capsule (rounded rod) between two points."""
        a, b = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
        length = float(np.linalg.norm(b - a))
        m = trimesh.creation.capsule(height=max(length, 1e-4), radius=radius, count=[8, 8])
        direction = (b - a) / max(length, 1e-9)
        m.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], direction))
        return self.add(_placed(m, tuple((a + b) / 2)), color)

    def arc(
        self,
        center: tuple[float, float, float],
        radius: float,
        tube: float,
        a0: float,
        a1: float,
        color: str | RGBA,
        plane: str = "xz",
        segments: int = 8,
    ) -> None:
        """Bent tube along a circular arc from angle a0 to a1 (radians) in the `plane` ('xz' or 'yz')."""
        angles = np.linspace(a0, a1, segments + 1)
        pts = []
        for a in angles:
            u, w = radius * np.cos(a), radius * np.sin(a)
            off = (u, 0.0, w) if plane == "xz" else (0.0, u, w)
            pts.append(tuple(np.asarray(center) + np.asarray(off)))
        for p, q in pairwise(pts):
            self.rod(p, q, tube, color, sections=8)
        for p in pts[1:-1]:
            self.sphere(tube, p, color, subdivisions=0)

    def build(self) -> tuple[trimesh.Trimesh, np.ndarray]:
        """Concatenate the parts into one mesh and its per-face RGBA colours (uint8)."""
        if not self._meshes:
            raise ValueError("a generator produced no parts")
        mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(self._meshes))  # Trimeshes concatenate to one
        colors = np.concatenate(
            [np.tile(np.asarray(c, dtype=np.uint8), (len(m.faces), 1)) for m, c in zip(self._meshes, self._colors)]
        )
        return mesh, colors


class Ctx:
    """Seeded sampling context of one generator call; every sampled value is recorded in `params`."""

    def __init__(self, spec: CategorySpec, rng: np.random.Generator, variant: Variant) -> None:
        self.spec = spec
        self.rng = rng
        self.variant = variant
        self.body: RGBA = variant.rgba
        self.params: dict[str, Any] = {}

    def dim(self, axis: str, lo: float | None = None, hi: float | None = None) -> float:
        """Sample a main dimension uniformly in the table range, narrowed to [lo, hi] where that overlaps."""
        tlo, thi = self.spec.range(axis)
        a = tlo if lo is None else min(max(lo, tlo), thi)
        b = thi if hi is None else max(min(hi, thi), a)
        return self.set(axis, float(self.rng.uniform(a, b)))

    def set(self, name: str, value: Any) -> Any:
        """Record a derived parameter (clipping main dimensions to their table range)."""
        if name in ("depth", "width", "height"):
            tlo, thi = self.spec.range(name)
            value = float(min(max(value, tlo), thi))
        self.params[name] = round(value, 6) if isinstance(value, float) else value
        return value

    def u(self, name: str, lo: float, hi: float) -> float:
        """Sample a secondary parameter uniformly in [lo, hi]."""
        return self.set(name, float(self.rng.uniform(lo, hi)))

    def pick(self, name: str, options: list[Any] | tuple[Any, ...]) -> Any:
        """Pick one option uniformly."""
        return self.set(name, options[int(self.rng.integers(len(options)))])

    def flag(self, name: str, p: float) -> bool:
        """True with probability p."""
        return bool(self.set(name, bool(self.rng.random() < p)))

    def dims(self) -> tuple[float, float, float]:
        """The sampled target extents (depth, width, height); a generator must have set all three."""
        missing = [a for a in ("depth", "width", "height") if a not in self.params]
        if missing:
            raise RuntimeError(f"generator {self.spec.name!r} did not set {missing}; call ctx.dim() or ctx.set()")
        return (float(self.params["depth"]), float(self.params["width"]), float(self.params["height"]))
