"""`generate(category, seed)`: one deterministic procedural street object with its metadata (ProceduralAsset)."""

from __future__ import annotations

import re
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import trimesh
from trimesh.visual import ColorVisuals

from retrieval.procedural import gen_clutter, gen_furniture, gen_nonstandard, gen_standard
from retrieval.procedural.parts import Ctx, Parts
from retrieval.procedural.spec import CategorySpec, load_recipes

RECIPES: dict[str, CategorySpec] = load_recipes()

GENERATORS: dict[str, Callable[[Ctx, Parts], str]] = {
    **gen_standard.GENERATORS,
    **gen_nonstandard.GENERATORS,
    **gen_furniture.GENERATORS,
    **gen_clutter.GENERATORS,
}

if set(GENERATORS) != set(RECIPES):
    raise RuntimeError(
        f"recipes.csv and the generators disagree: table-only {sorted(set(RECIPES) - set(GENERATORS))}, "
        f"generator-only {sorted(set(GENERATORS) - set(RECIPES))}; add the missing row or generator"
    )


def category_names() -> list[str]:
    """Names of all procedural categories, in table order."""
    return list(RECIPES)


@dataclass
class ProceduralAsset:
    """A generated street object: mesh (metres, +z up, base z=0, x/y-centred, front +x) plus catalog metadata."""

    category: str
    seed: int
    object_class: str
    zones: list[str]
    mesh: trimesh.Trimesh
    face_colors: np.ndarray
    color: str
    material: str
    dims: tuple[float, float, float]
    mass: float
    description: str
    synonyms: list[str]
    params: dict[str, Any] = field(default_factory=dict)
    watertight: bool = False

    @property
    def palette(self) -> np.ndarray:
        """Distinct face colours (RGBA uint8) in order of first appearance."""
        _, idx = np.unique(self.face_colors, axis=0, return_index=True)
        return self.face_colors[np.sort(idx)]


def _spec(category: str) -> CategorySpec:
    if category not in RECIPES:
        raise ValueError(f"unknown procedural category {category!r}; valid categories: {', '.join(RECIPES)}")
    return RECIPES[category]


def _fit(mesh: trimesh.Trimesh, target: tuple[float, float, float]) -> tuple[float, float, float]:
    """Scale the mesh so its bounding box equals `target`, then put its base at z=0 centred on x/y."""
    lo, hi = mesh.bounds
    scale = np.asarray(target) / np.maximum(hi - lo, 1e-9)
    mesh.apply_transform(np.diag([*scale, 1.0]))
    lo, hi = mesh.bounds
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    sx, sy, sz = (float(s) for s in scale)
    return sx, sy, sz


def _mass(spec: CategorySpec, dims: tuple[float, float, float]) -> float:
    """Interpolate the table's mass range by where the sampled size sits in its ranges (bigger is heavier)."""
    fr = []
    for axis, v in zip(("depth", "width", "height"), dims):
        lo, hi = spec.range(axis)
        fr.append(0.5 if hi <= lo else (v - lo) / (hi - lo))
    t = float(np.clip(np.mean(fr), 0.0, 1.0))
    return round(spec.mass[0] + t * (spec.mass[1] - spec.mass[0]), 3)


def generate(category: str, seed: int) -> ProceduralAsset:
    """Generate `category` deterministically from `seed` (dimensions in the table's real-world ranges)."""
    spec = _spec(category)
    # Seeding with the category too keeps seed 0 of different categories independent.
    rng = np.random.default_rng([int(seed), zlib.crc32(category.encode())])
    variant = spec.variants[int(rng.integers(len(spec.variants)))]
    ctx = Ctx(spec, rng, variant)
    parts = Parts()
    detail = GENERATORS[category](ctx, parts)
    target = ctx.dims()
    mesh, colors = parts.build()
    visual = cast(ColorVisuals, mesh.visual)  # parts are trimesh.creation primitives, which carry colour visuals
    visual.face_colors = colors  # also on the mesh, for viewers and renderers that read trimesh visuals
    # Parts are laid out to fill the target box; the fit absorbs small overhangs (lamp lenses, handles) so that
    # recorded dims equal the mesh bounds exactly. Its scale is recorded so a generator drifting off is visible.
    scale = _fit(mesh, target)
    lo, hi = mesh.bounds
    depth, width, height = (round(float(v), 6) for v in hi - lo)
    dims = (depth, width, height)
    params = dict(ctx.params)
    params.update(variant=f"{variant.color} {variant.material}", fit_scale=[round(s, 4) for s in scale])
    values = {
        "depth": dims[0],
        "width": dims[1],
        "height": dims[2],
        "color": variant.color,
        "material": variant.material,
        "detail": detail,
    }
    description = " ".join(spec.description.format(**values).split())
    description = re.sub(r"\ba ([aeiou])", r"an \1", description)
    return ProceduralAsset(
        category=category,
        seed=int(seed),
        object_class=spec.object_class,
        zones=list(spec.zones),
        mesh=mesh,
        face_colors=colors,
        color=variant.color,
        material=variant.material,
        dims=dims,
        mass=_mass(spec, dims),
        description=description,
        synonyms=list(spec.synonyms),
        params=params,
        watertight=bool(mesh.is_watertight),
    )
