"""Object placement per class: periodic standard infrastructure, zoned non-standard, clutter, buildings."""

from __future__ import annotations

import math
import warnings
from collections import Counter
from typing import Any

import numpy as np
import shapely
from shapely import lib
from shapely.geometry import Polygon

from catalogs.categories import CATEGORIES, NAMES, of_class, zones_of_class
from sim.scene.categories import CategorySampler
from sim.scene.occupancy import GAP, Occupancy, quad_polygon, rect
from sim.scene.rows import Row, fill_rows
from sim.scene.sidewalks import Sidewalk, Zone
from sim.scene.spec import round_points, round_value

_contains_scalar = lib.contains_scalar  # what Polygon.contains calls for one geometry
FILL_ZONES = ("near_road_buffer", "furnishing", "frontage_buffer", "frontage")


class Placer:
    """Places objects one by one, refusing those that leave their zone, overlap, or block the clear path."""

    def __init__(self, cfg: dict[str, Any], rng: np.random.Generator, catalog: Any, sampler: CategorySampler) -> None:
        self.cfg, self.rng, self.catalog, self.sampler = cfg, rng, catalog, sampler
        self.objects: list[dict[str, Any]] = []
        self.occupied = Occupancy()
        self.object_area = 0.0  # footprint area of placed non-building objects, summed at their exact sizes
        self.refused: Counter[str] = Counter()
        self.fallback: list[str] = []
        self.z = round_value(float(cfg["curb_height"]))  # objects stand on the curb, stored at 0.1 mm
        self._has = {cat: catalog is not None and len(catalog.candidates(cat)) > 0 for cat in CATEGORIES}
        self.min_depth = {cat: self._min_depth(cat) for cat in CATEGORIES}
        self._zones: dict[int, tuple[Polygon, tuple[float, float, float, float]]] = {}

    def in_catalog(self, category: str) -> bool:
        """Whether the catalog holds an asset of `category` (asked once per category)."""
        return self._has.get(category, False)  # every category the placer asks for is in CATEGORIES

    def _min_depth(self, category: str) -> float:
        if self.in_catalog(category):
            return float(self.catalog.table.size[self.catalog.candidates(category), 0].min())
        return CATEGORIES[category].size[0]

    def set_keep_out(self, polys: list[Polygon]) -> None:
        """Areas no object may touch (clear-path corridors, ramp approaches)."""
        self.occupied.set_keep_out(polys)

    def asset(
        self, category: str, zone: str, max_depth: float, max_width: float | None = None
    ) -> tuple[str | None, list[float]] | None:
        """(asset_id, size) of an asset of `category` that fits, a fallback box, or None when nothing fits."""
        if self.in_catalog(category):
            rec = self.catalog.sample(self.rng, category, zone=zone, max_depth=max_depth, max_width=max_width)
            if rec is None:
                rec = self.catalog.sample(self.rng, category, max_depth=max_depth, max_width=max_width)
            return None if rec is None else (rec.asset_id, [float(value) for value in rec.size])
        self._note_fallback(category)
        size = list(CATEGORIES[category].size)
        return None if size[0] > max_depth or (max_width is not None and size[1] > max_width) else (None, size)

    def _note_fallback(self, category: str) -> None:
        if category not in self.fallback:
            self.fallback.append(category)
            src = (
                "no catalog was given"
                if self.catalog is None
                else f"catalog {self.catalog.path} has no {category!r} asset"
            )
            warnings.warn(f"{src}; placing default-size boxes for category {category!r}", stacklevel=5)

    def note_fallback(self, categories: np.ndarray) -> None:
        """Record (and warn once about) the categories, by NAMES index, placed as fallback boxes."""
        for k in np.unique(categories).tolist():
            self._note_fallback(NAMES[k])

    def zone_shape(self, zone: Zone) -> tuple[Polygon, tuple[float, float, float, float]]:
        """The zone's polygon (prepared) and its bounds, computed once per polygon."""
        zp = zone.polygon
        ent = self._zones.get(id(zp))
        if ent is None or ent[0] is not zp:
            if not shapely.is_prepared(zp):
                shapely.prepare(zp)
            x0, y0, x1, y1 = zp.bounds
            ent = self._zones[id(zp)] = (zp, (float(x0), float(y0), float(x1), float(y1)))
        return ent

    def try_place(
        self,
        sw: Sidewalk,
        zone: Zone,
        category: str,
        asset: tuple[str | None, list[float]],
        center: np.ndarray | tuple[float, float],
        yaw: float,
        *,
        keep_out: bool = True,
    ) -> bool:
        """Place one object if its footprint lies in `zone`, overlaps nothing and (optionally) avoids keep-outs."""
        depth, width, height = asset[1]
        x, y = float(center[0]), float(center[1])
        cos_yaw, sn = math.cos(yaw), math.sin(yaw)
        corners, pb = rect(x, y, cos_yaw, sn, depth, width)
        ent = self._zones.get(id(zone.polygon))
        if ent is None or ent[0] is not zone.polygon:
            ent = self.zone_shape(zone)
        zp, (zx0, zy0, zx1, zy1) = ent
        # A corner outside the zone's bounds is outside the zone: most refusals end here, without shapely.
        # (The zone containing the footprint implies every corner lies in the zone, so no separate corner test.)
        if pb[0] < zx0 or pb[1] < zy0 or pb[2] > zx1 or pb[3] > zy1:
            return False
        poly = quad_polygon(corners)
        if not _contains_scalar(zp, poly):  # zp.contains(poly), minus shapely's argument handling
            return False
        check, cb = rect(x, y, cos_yaw, sn, depth + GAP, width + GAP)
        if not self.occupied.free(poly, pb, check, cb, keep_out):
            return False
        self.occupied.add(check, cb)
        if zone.kind != "building":
            self.object_area += depth * width
        # Objects are stored as the spec holds them (sim.scene.spec.canonical: 0.1 mm), so the generator need not
        # walk hundreds of them again; placement itself used the exact corners above.
        self.objects.append(
            {
                "id": f"o{len(self.objects)}",
                "asset_id": asset[0],
                "category": category,
                "object_class": CATEGORIES[category].object_class,
                "zone": zone.kind,
                "sidewalk_id": sw.id,
                "position": [round_value(x), round_value(y), self.z],
                "yaw": round_value(math.atan2(math.sin(yaw), math.cos(yaw))),  # wrapped to (-pi, pi]
                "size": [round_value(float(depth)), round_value(float(width)), round_value(float(height))],
                "footprint": round_points(corners),
            }
        )
        return True

    def _count(self, per_100m: float, length: float) -> int:
        x = per_100m / 100.0 * float(self.cfg["object_density"]) * length
        return int(x) + int(self.rng.random() < x - int(x))

    def standard(self, sw: Sidewalk) -> None:
        """Standard infrastructure at regular stations along the curb, in the furnishing zone."""
        zone = sw.zone("furnishing") or sw.zone("near_road_buffer")
        rho = float(self.cfg["object_density"])
        if zone is None or rho <= 0:
            return
        spacing = float(self.cfg["standard_spacing"]) / rho
        s0, s1 = sw.s_range
        stations = np.arange(s0 + 1.0 + self.rng.uniform(0, min(spacing, s1 - s0)), s1 - 1.0, spacing)
        allowed = [category for category in of_class("standard") if self.min_depth[category] <= zone.width - 0.05]
        cl, side = sw.roadway.centerline, sw.side
        for station in stations:
            cat = self.sampler.draw(self.rng, "standard", allowed)
            if cat is None:
                return
            asset = self.asset(cat, "furnishing", zone.width - 0.05)
            ok = False
            if asset is not None:
                for ds in (0.0, 0.8, -0.8, 1.6)[: max(1, int(self.cfg["placement_tries"]))]:
                    x, y, heading = cl.point_xy(station + ds, side * (zone.d0 + zone.d1) / 2)
                    if self.try_place(sw, zone, cat, asset, (x, y), heading + side * math.pi / 2):
                        ok = True
                        break
            if not ok:
                self.refused[cat] += 1

    def _random_in(
        self, sw: Sidewalk, zone: Zone, category: str, asset: tuple[str | None, list[float]], yaw_mode: str
    ) -> bool:
        depth, width, _ = asset[1]
        half = max(depth, width) / 2 if yaw_mode == "random" else depth / 2
        lo, hi = zone.d0 + half, zone.d1 - half
        if hi < lo:
            return False
        cl, side = sw.roadway.centerline, sw.side
        for _ in range(max(1, int(self.cfg["placement_tries"]))):
            s = self.rng.uniform(*sw.s_range)
            d = self.rng.uniform(lo, hi)
            x, y, heading = cl.point_xy(s, side * d)
            if yaw_mode == "random":
                yaw = float(self.rng.uniform(-math.pi, math.pi))
            else:
                # Furnishing objects face the walkway (away from the road); frontage objects face the road.
                yaw = heading + side * math.pi / 2 * (1 if zone.kind == "furnishing" else -1)
            if self.try_place(sw, zone, category, asset, (x, y), yaw):
                return True
        return False

    def non_standard(self, sw: Sidewalk) -> None:
        """Non-standard infrastructure at random spots in their designated zones."""
        present = {z.kind: z for z in sw.zones}
        length = sw.s_range[1] - sw.s_range[0]
        for _ in range(self._count(float(self.cfg["non_standard_per_100m"]), length)):
            allowed = [
                category
                for category in of_class("non_standard")
                if any(
                    z in present and self.min_depth[category] <= present[z].width for z in CATEGORIES[category].zones
                )
            ]
            cat = self.sampler.draw(self.rng, "non_standard", allowed)
            if cat is None:
                return
            zones = [
                present[z] for z in CATEGORIES[cat].zones if z in present and self.min_depth[cat] <= present[z].width
            ]
            zone = zones[int(self.rng.integers(len(zones)))]
            asset = self.asset(cat, zone.kind, zone.width)
            if asset is None or not self._random_in(sw, zone, cat, asset, "aligned"):
                self.refused[cat] += 1

    def clutter(self, sw: Sidewalk) -> None:
        """Clutter anywhere on the sidewalk except the clear-path corridor."""
        zones = [z for z in sw.zones if z.kind in zones_of_class("clutter")]
        length = sw.s_range[1] - sw.s_range[0]
        for _ in range(self._count(float(self.cfg["clutter_per_100m"]), length)):
            zone = zones[int(self.rng.integers(len(zones)))]
            cat = self.sampler.draw(self.rng, "clutter")
            if cat is None:
                return
            asset = self.asset(cat, zone.kind, zone.width)
            if asset is None or not self._random_in(sw, zone, cat, asset, "random"):
                self.refused[cat] += 1

    def fill(self, sw: Sidewalk, gap_scale: float = 1.0) -> None:
        """The `paper` density model: rows of objects along every furniture zone, gaps drawn around `fill_gap`.

        MetaUrban-12K's sidewalks are lined with furniture 0.7 m apart on average (the paper's appendix). Each
        zone beside the clear path (near-road buffer, furnishing, frontage buffer, frontage) is walked from one
        end to the other: at each step one object of a category designated for the zone (or, with probability
        `fill_clutter`, a clutter item) is placed at a random lateral offset, then the walk skips its width plus a
        gap ~ Gamma(2, fill_gap / 2 / rho). Objects that do not fit are skipped, so the clear-path corridor and
        the ramp approaches stay free (the keep-outs hold as for every other pass).
        """
        rho = float(self.cfg["object_density"])
        if rho <= 0:
            return
        gap_mean = float(self.cfg["fill_gap"]) * gap_scale / rho
        p_clutter = float(self.cfg["fill_clutter"])
        rows = []
        for zone in sw.zones:
            if zone.kind == "clear":
                # Parked scooters, bicycles and bags along the edges of the walkway, outside the kept corridor.
                margin = 0.5 * (zone.width - float(self.cfg["min_clear_width"]))
                if margin >= 0.45:
                    rows += [
                        Row(zone, zone.d0, zone.d0 + margin, 2.0 * gap_mean, 1.0),
                        Row(zone, zone.d1 - margin, zone.d1, 2.0 * gap_mean, 1.0),
                    ]
                continue
            if zone.kind not in FILL_ZONES:
                continue
            # Wide zones (frontage of commercial templates) hold several rows, as cafe seating and displays do.
            num_bands = max(1, int(zone.width // float(self.cfg["fill_row_width"])))
            band = zone.width / num_bands
            rows += [
                Row(zone, zone.d0 + band_idx * band, zone.d0 + (band_idx + 1) * band, gap_mean, p_clutter)
                for band_idx in range(num_bands)
            ]
        fill_rows(self, sw, rows)

    def buildings(self, sw: Sidewalk) -> int:
        """Building facades side by side along the building zone; returns how many spots were skipped."""
        zone = sw.building
        if zone is None:
            return 0
        cl, side = sw.roadway.centerline, sw.side
        ends = cl.project(np.asarray(zone.polygon.exterior.coords))
        s, s_end = float(ends.min()), float(ends.max())
        skipped = 0
        # The paper model lines the street with buildings that fill the zone: a catalog facade (its look and
        # height) or a box, stretched to the zone's depth and the drawn width (the world fits a mesh into its
        # spec box), and on curves shallower and narrower until it fits the bent zone. A catalog facade is
        # 4-12 m deep, the zone 18-26 m: at its own depth the street would lose a third of its built area.
        fill = self.cfg["density_model"] == "paper"
        while s < s_end - 4.0:
            want = float(self.rng.uniform(8.0, 20.0))
            asset = (
                None
                if fill and not self.in_catalog("building_facade")
                else self.asset("building_facade", "building", zone.width, want)
            )
            if fill:
                height = (
                    asset[1][2] if asset is not None and asset[0] is not None else float(self.rng.uniform(6.0, 30.0))
                )
                asset = (None if asset is None else asset[0], [zone.width, want, height])
            elif asset is None:
                skipped += 1
                s += 3.0
                continue
            elif asset[0] is None:
                asset = (None, [zone.width, want, float(self.rng.uniform(6.0, 30.0))])
            placed = False
            # Outside the paper model only fallback boxes may be narrowed; a catalog mesh keeps its real size.
            shapes = [(1.0, 1.0), (1.0, 0.6), (1.0, 0.35)] if fill or asset[0] is None else [(1.0, 1.0)]
            if fill:
                shapes += [(0.8, 0.6), (0.8, 0.35), (0.6, 0.35), (0.6, 0.2)]
            for deep, shrink in shapes:
                size = [asset[1][0] * deep, max(asset[1][1] * shrink, 3.0), asset[1][2]]
                sc = s + size[1] / 2 + 0.1
                x, y, heading = cl.point_xy(sc, side * (zone.d0 + size[0] / 2))
                if self.try_place(
                    sw, zone, "building_facade", (asset[0], size), (x, y), heading - side * math.pi / 2, keep_out=False
                ):
                    s = sc + size[1] / 2 + 0.1
                    placed = True
                    break
            if not placed:
                skipped += 1
                s += 3.0
        return skipped
