"""generate_scene: config + seed (+ catalog) -> scene spec (docs/scene_spec.md)."""

from __future__ import annotations

import gc
import warnings
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from sim.scene.categories import CategorySampler, load_distribution
from sim.scene.config import resolve_config
from sim.scene.geometry import ring_coords
from sim.scene.grid import CROSSWALK, RAMP, SIDEWALK, encode_walkable, rasterize
from sim.scene.occupancy import corridor
from sim.scene.placement import Placer
from sim.scene.roads import generate_network, lane_lines
from sim.scene.scene import SPEC_VERSION
from sim.scene.sidewalks import build_crosswalks, build_sidewalks
from sim.scene.spec import canonical
from sim.scene.terrain import place_terrain, terrain_stats


def _open_catalog(catalog: Any) -> tuple[Any, str | None]:
    if catalog is None:
        return None, None
    if isinstance(catalog, (str, Path)):
        from catalogs.reader import read_catalog

        return read_catalog(catalog), str(catalog)
    return catalog, str(getattr(catalog, "path", catalog))


def _line(ls: Any) -> list[list[float]]:
    return np.asarray(ls.coords).tolist()


def _bounds(polys: list[Any]) -> tuple[float, float, float, float]:
    # The bounds of a union are the extremes of the parts' bounds; no need to build the union.
    b = shapely.bounds(np.asarray(polys, dtype=object))
    return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())


def generate_scene(config: dict[str, Any] | None, seed: int, catalog: Any = None) -> dict[str, Any]:
    """Generate one scene spec from a strict config, a seed and an optional catalog (reader or path)."""
    # A scene allocates tens of thousands of small objects and no garbage cycles worth collecting meanwhile:
    # pausing the cyclic collector spares its repeated passes (~10 % of the time); it resumes afterwards.
    paused = gc.isenabled()
    if paused:
        gc.disable()
    try:
        return _generate_scene(config, seed, catalog)
    finally:
        if paused:
            gc.enable()


def _generate_scene(config: dict[str, Any] | None, seed: int, catalog: Any) -> dict[str, Any]:
    cfg = resolve_config(config)
    reader, catalog_name = _open_catalog(catalog)
    if reader is not None and cfg["assets"] != "all":
        from sim.scene.dataset import HELD_OUT_CATEGORIES

        reader = reader.asset_split(cfg["assets"], tuple(HELD_OUT_CATEGORIES))
    rng = np.random.default_rng(int(seed))
    freq = load_distribution(cfg["country"], cfg["distribution_path"]) if cfg["country"] else None
    sampler = CategorySampler(cfg["exclude_categories"], freq)
    for w in sampler.warnings:
        warnings.warn(w, stacklevel=2)

    blocks = generate_network(cfg, rng)
    sidewalks = build_sidewalks(blocks, cfg, rng)
    crosswalks = build_crosswalks(blocks, sidewalks, cfg, rng)

    placer = Placer(cfg, rng, reader, sampler)
    keep = [corridor(sw, float(cfg["min_clear_width"])) for sw in sidewalks if cfg["min_clear_width"] > 0]
    placer.set_keep_out(keep + [k for sw in sidewalks for k in sw.keep_out])
    skipped = 0
    for sw in sidewalks:
        placer.standard(sw)
    if cfg["density_model"] == "paper":
        for sw in sidewalks:
            placer.fill(sw)
    else:
        for sw in sidewalks:
            placer.non_standard(sw)
        for sw in sidewalks:
            placer.clutter(sw)
    for sw in sidewalks:
        skipped += placer.buildings(sw)
    if cfg["density_model"] == "paper":
        # Small scenes (one short block) fall below the paper's minimum count: fill the gaps left, with ever
        # smaller gaps, until the scene holds min_objects.
        for round_ in range(6):
            if len(placer.objects) >= int(cfg["min_objects"]):
                break
            for sw in sidewalks:
                placer.fill(sw, gap_scale=0.75 ** (round_ + 1))

    terrain = place_terrain(sidewalks, placer, cfg, int(seed))  # after every object: none of them moves

    walk_polys = [sw.polygon for sw in sidewalks]
    cw_polys = [c.polygon for c in crosswalks]
    ramp_polys = [r for c in crosswalks for _, r in c.ramps]
    wb = _bounds(walk_polys + cw_polys)
    res = float(cfg["grid_resolution"])
    pad = 2 * res
    mask, origin = rasterize(
        [(SIDEWALK, walk_polys), (CROSSWALK, cw_polys), (RAMP, ramp_polys)],
        (wb[0] - pad, wb[1] - pad, wb[2] + pad, wb[3] + pad),
        res,
    )
    everything = [b.polygon for b in blocks] + walk_polys + [sw.building.polygon for sw in sidewalks if sw.building]
    bounds = list(_bounds(everything))

    objects = placer.objects
    by_class = Counter(o["object_class"] for o in objects)
    obj_area = float(placer.object_area)
    walk_area = float(sum(p.area for p in walk_polys + cw_polys))
    stats = {
        "objects": len(objects),
        "objects_by_class": {k: by_class.get(k, 0) for k in ("standard", "non_standard", "clutter")},
        "buildings": sum(1 for o in objects if o["category"] == "building_facade"),
        "refused": dict(sorted(placer.refused.items())),
        "refused_total": int(sum(placer.refused.values())),
        "building_spots_skipped": skipped,
        "fallback_categories": sorted(placer.fallback),
        "street_length_m": float(sum(b.through_length for b in blocks)),
        "clear_path_length_m": float(sum(sw.clear_path.length for sw in sidewalks)),
        "walkable_area_m2": walk_area,
        "object_area_m2": obj_area,
        "object_area_fraction": obj_area / walk_area if walk_area else 0.0,
        "blocks": "".join(b.code for b in blocks),
        "sidewalks": len(sidewalks),
        "templates": dict(sorted(Counter(sw.template for sw in sidewalks).items())),
        "crosswalks": len(crosswalks),
        "distribution": cfg["country"] or "uniform",
        "terrain": terrain_stats(terrain),
    }
    spec = {
        "version": SPEC_VERSION,
        "seed": int(seed),
        "config": cfg,
        "catalog": catalog_name,
        "bounds": bounds,
        "curb_height": float(cfg["curb_height"]),
        "roads": [
            {
                "id": b.id,
                "block": b.code,
                "polygon": ring_coords(b.polygon),
                "centerlines": [w.centerline.points.tolist() for w in b.roadways if w.sides != (1,)],
                "roadway_ids": [w.id for w in b.roadways if w.sides != (1,)],
                "lanes": b.lanes,
                "lane_width": b.lane_width,
                "lane_lines": [ln for w in b.roadways for ln in lane_lines(w, b.lanes, b.lane_width)],
                "island": ring_coords(b.island) if b.island is not None else None,
            }
            for b in blocks
        ],
        "sidewalks": [
            {
                "id": sw.id,
                "road_id": sw.road_id,
                "roadway_id": sw.roadway.id,
                "side": sw.side_name,
                "template": sw.template,
                "polygon": ring_coords(sw.polygon),
                "edge": _line(sw.edge),
                "zones": [
                    {"kind": z.kind, "polygon": ring_coords(z.polygon), "width": z.width}
                    for z in sw.zones + ([sw.building] if sw.building else [])
                ],
                "clear_path": _line(sw.clear_path),
            }
            for sw in sidewalks
        ],
        "crosswalks": [
            {
                "id": c.id,
                "road_id": c.road_id,
                "polygon": ring_coords(c.polygon),
                "width": c.width,
                "ends": [e.tolist() for e in c.ends],
                "sidewalks": [s.id for s in c.sidewalks],
                "ramps": [{"sidewalk_id": sid, "polygon": ring_coords(p)} for sid, p in c.ramps],
            }
            for c in crosswalks
        ],
        "walkable": encode_walkable(mask, origin, res),
        "stats": stats,
    }
    spec = canonical(spec)
    spec["objects"] = objects  # placed in canonical form already (Placer.try_place)
    spec["terrain"] = terrain  # likewise (sim.scene.terrain.patch_record)
    return spec
