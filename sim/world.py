"""Scene (`sim.scene.Scene`, a parsed `curbside.scene/1` spec) -> static PyBullet world: ground, roads, raised
sidewalks with curbs, curb ramps, crosswalks, buildings and static objects.

Surfaces are static concave triangle meshes (extruded polygons: a constrained Delaunay triangulation of
the top plus side walls, which are the curbs); ramps are convex wedges; terrain patches (sim.terrain.patches) are
meshes on the sidewalk slab with their surface's friction, bodies of kind "sidewalk" (a stair's riser is touched
as a curb); objects get box collision from their `size` by default, or the convex hull of their catalog mesh when
`collision="convex"`.
A `World` is built once per scene; environments reuse it across resets on the same scene.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.geometry.polygon import orient

from kernel.quiet import pybullet as p
from sim.meshes import extrusion_mesh, mesh_shape, polygons, welded
from sim.palette import SURFACE, category_color, terrain_colour
from sim.scene.scene import Scene, SceneError, as_scene
from sim.terrain import patches

# Body kinds: what a contact with or a ray hit on that body means.
SURFACE_KINDS = ("ground", "sidewalk", "ramp")


WALL_NZ = 0.5  # a contact whose normal is flatter than this is a wall (a curb side), not the ground


def touching(
    client: int,
    body: int,
    kinds: Mapping[int, str],
    extra: Mapping[int, str],
    hits: set[str],
    bodies: set[int] | None = None,
) -> None:
    """Add to `hits` what `body` touches now: the kind of each body (`extra` first, then `kinds`, else
    "object"), and "curb" for a surface touched through a wall-like contact normal; and to `bodies` (unless None)
    the ids of the bodies touched that are not a surface."""
    for cp in p.getContactPoints(bodyA=body, physicsClientId=client):
        if cp[8] > 1e-3:
            continue  # within the contact margin but not touching
        kind = extra.get(cp[2]) or kinds.get(cp[2], "object")
        if kind in SURFACE_KINDS:
            if abs(cp[7][2]) < WALL_NZ:
                hits.add("curb")
        else:
            hits.add(kind)
            if bodies is not None:
                bodies.add(cp[2])


def _obj_vertices(path: str) -> np.ndarray:
    """Vertex positions of a Wavefront OBJ file (enough for a convex hull)."""
    out = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.startswith("v "):
                out.append([float(token) for token in line.split()[1:4]])
    if not out:
        raise SceneError(f"mesh {path} has no vertices; rebuild the asset or use collision='box'")
    return np.asarray(out)


class World:
    """The static PyBullet world built from one scene; `kinds` maps body id -> what it is."""

    def __init__(
        self,
        scene: Scene | Mapping[str, Any],
        *,
        client: int | None = None,
        gui: bool = False,
        collision: str = "box",
        catalog: Any = None,
        visual_meshes: bool = False,
        physics_dt: float = 0.02,
    ) -> None:
        self.scene = as_scene(scene)  # a dict is parsed (checked) here, once
        if collision not in ("box", "convex"):
            raise SceneError(f"unknown collision {collision!r}; valid: box, convex")
        self.curb_height = self.scene.curb_height
        self.owns_client = client is None
        self.client = p.connect(p.GUI if gui else p.DIRECT) if client is None else client
        self.kinds: dict[int, str] = {}
        self.object_ids: list[int] = []
        self.object_index: dict[int, int] = {}  # body id -> index into scene.objects
        self._collision = collision
        self._catalog = catalog
        self._visual_meshes = visual_meshes
        p.resetSimulation(physicsClientId=self.client)
        p.setGravity(0, 0, -9.81, physicsClientId=self.client)
        p.setTimeStep(physics_dt, physicsClientId=self.client)
        # One solver pass per substep: the world holds one dynamic body, so more iterations buy nothing.
        p.setPhysicsEngineParameter(
            numSolverIterations=10, deterministicOverlappingPairs=1, physicsClientId=self.client
        )
        self._build()

    # -- building -----------------------------------------------------------------------------------
    def _add(self, kind: str, col: int, vis: int, pos=(0, 0, 0), orn=(0, 0, 0, 1), maximal: bool = True) -> int:
        # Maximal coordinates: a static btRigidBody instead of a fixed-base btMultiBody, which Bullet visits every
        # substep (250 static bodies: 98 -> 25 us a substep; a SocialNav step's Bullet time halves).
        body = p.createMultiBody(
            0,
            col,
            vis,
            basePosition=list(pos),
            baseOrientation=list(orn),
            useMaximalCoordinates=maximal,
            physicsClientId=self.client,
        )
        self.kinds[body] = kind
        return body

    def _mesh_body(
        self, kind: str, verts: list, idx: list, color, collide: bool = True, rolled_on: bool = False
    ) -> int | None:
        """A static triangle-mesh body; one that wheels roll on (`rolled_on`: sidewalk slabs, terrain patches) gets
        Bullet's internal-edge correction."""
        if not idx:
            return None
        client = self.client
        vis = mesh_shape(p.createVisualShape, verts, idx, rgbaColor=list(color), physicsClientId=client)
        if not collide:
            return self._add(kind, -1, vis)
        if not rolled_on:
            return self._add(kind, mesh_shape(p.createCollisionShape, verts, idx, physicsClientId=client), vis)
        # Welded, with the internal-edge correction, on a fixed-base multibody (the correction does not run for a
        # maximal-coordinates body): a wheel crossing an edge between two triangles of one flat surface rolls on
        # instead of bouncing off it (sim.meshes.welded).
        col = mesh_shape(
            p.createCollisionShape, *welded(verts, idx), flags=p.GEOM_CONCAVE_INTERNAL_EDGE, physicsClientId=client
        )
        return self._add(kind, col, vis, maximal=False)

    def _build(self) -> None:
        scene, client, curb_h = self.scene, self.client, self.curb_height
        xmin, ymin, xmax, ymax = scene.bounds
        cx, cy = 0.5 * (xmin + xmax), 0.5 * (ymin + ymax)
        hx, hy = 0.5 * (xmax - xmin) + 50.0, 0.5 * (ymax - ymin) + 50.0
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[hx, hy, 0.5], physicsClientId=client)
        vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=[hx, hy, 0.5], rgbaColor=list(SURFACE["ground"]), physicsClientId=client
        )
        self.ground = self._add("ground", col, vis, (cx, cy, -0.5))
        # Painted surfaces on the road are visual only: the ground plane carries the wheels there.
        for road in scene.roads:
            for poly in polygons(Polygon(road["polygon"]).buffer(0)):
                self._mesh_body("road", *extrusion_mesh(poly, 0.0, 0.002, walls=False), SURFACE["road"], collide=False)
        for cw in scene.crosswalks:
            for poly in polygons(Polygon(cw["polygon"]).buffer(0)):
                self._mesh_body(
                    "crosswalk", *extrusion_mesh(poly, 0.0, 0.004, walls=False), SURFACE["crosswalk"], collide=False
                )
        slabs, wedges = sidewalk_solids(scene, curb_h)
        for pts, z in wedges:
            self._wedge("ramp", pts, z)
        rng = np.random.default_rng(scene.seed)
        for sw, sw_slabs in zip(scene.sidewalks, slabs):
            for poly in sw_slabs:
                self._mesh_body("sidewalk", *extrusion_mesh(poly, 0.0, curb_h), SURFACE["sidewalk"], rolled_on=True)
            for zone in sw.get("zones", []):
                if zone.get("kind") == "building":
                    height = float(rng.uniform(6.0, 18.0))
                    for poly in polygons(Polygon(zone["polygon"]).buffer(0)):
                        self._mesh_body("building", *extrusion_mesh(poly, 0.0, height), SURFACE["building"])
        self.patch_index: dict[int, int] = {}  # body id -> index into scene.terrain
        for k, rec in enumerate(scene.terrain):
            body = self._mesh_body(
                "sidewalk", *patches.mesh(rec), terrain_colour(rec["kind"], rec["surface"]), rolled_on=True
            )
            assert body is not None  # a patch's mesh always has triangles (its skirt's at least)
            p.changeDynamics(body, -1, lateralFriction=patches.friction(rec), physicsClientId=client)
            self.patch_index[body] = k
        self._friction = patches.FrictionIndex(scene.terrain)
        for i, obj in enumerate(scene.objects):
            body = self._build_object(obj)
            self.object_ids.append(body)
            self.object_index[body] = i

    def _wedge(self, kind: str, pts: np.ndarray, z: np.ndarray) -> None:
        top = [[float(x), float(y), float(zz)] for (x, y), zz in zip(pts, z)]
        verts = top + [[float(x), float(y), -0.02] for x, y in pts]
        col = mesh_shape(p.createCollisionShape, verts, physicsClientId=self.client)
        idx = []
        for k in range(1, len(pts) - 1):
            idx += [0, k, k + 1]
        vis = mesh_shape(p.createVisualShape, top, idx, rgbaColor=list(SURFACE[kind]), physicsClientId=self.client)
        self._add(kind, col, vis)

    def _build_object(self, obj: Mapping[str, Any]) -> int:
        client = self.client
        x, y, z = (float(value) for value in obj["position"])
        depth, width, hgt = (max(float(value), 0.02) for value in obj["size"])
        orn = p.getQuaternionFromEuler([0, 0, float(obj.get("yaw", 0.0))])
        color = list(category_color(str(obj.get("category", "object"))))
        size = np.array([depth, width, hgt])
        hull = self._mesh_path(obj, "collision_path") if self._collision == "convex" else None
        if hull is not None:
            value = _obj_vertices(hull)
            lo, hi = value.min(0), value.max(0)
            # Fit the hull into the spec's box: base centred on the footprint, bottom on the surface.
            value = (value - [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]) * (size / np.maximum(hi - lo, 1e-6))
            col, origin = mesh_shape(p.createCollisionShape, value.tolist(), physicsClientId=client), (x, y, z)
        else:
            col = p.createCollisionShape(
                p.GEOM_BOX, halfExtents=[depth / 2, width / 2, hgt / 2], physicsClientId=client
            )
            origin = (x, y, z + hgt / 2)
        look = self._mesh_path(obj, "mesh_path") if self._visual_meshes else None
        if look is not None:
            value = _obj_vertices(look)
            lo, hi = value.min(0), value.max(0)
            scale = size / np.maximum(hi - lo, 1e-6)
            # The textured mesh in the same box, relative to the body's origin (the box centre, or the base).
            at = [-(lo[0] + hi[0]) / 2 * scale[0], -(lo[1] + hi[1]) / 2 * scale[1], -lo[2] * scale[2] + z - origin[2]]
            vis = p.createVisualShape(
                p.GEOM_MESH, fileName=look, meshScale=scale.tolist(), visualFramePosition=at, physicsClientId=client
            )  # no rgbaColor: the mesh's baked texture shows
        else:
            vis = p.createVisualShape(
                p.GEOM_BOX,
                halfExtents=[depth / 2, width / 2, hgt / 2],
                rgbaColor=color,
                visualFramePosition=[0.0, 0.0, z + hgt / 2 - origin[2]],
                physicsClientId=client,
            )
        return self._add("object", col, vis, origin, orn)

    def _mesh_path(self, obj: Mapping[str, Any], field: str) -> str | None:
        """The catalog OBJ of `obj`'s asset named by `field` (mesh_path: textured; collision_path: the hull,
        falling back to mesh_path), or None."""
        if self._catalog is None or not obj.get("asset_id"):
            return None
        rec = self._catalog.get(obj["asset_id"])
        rel = getattr(rec, field, None) or getattr(rec, "mesh_path", None)
        path = self._catalog.resolve(rel)
        if path is None or path.suffix.lower() != ".obj" or not path.exists():
            return None
        return str(path)

    # -- queries ------------------------------------------------------------------------------------
    def surface_height(self, x: float, y: float) -> float:
        """Height of the driving surface under (x, y), from a vertical ray (objects excluded by the caller)."""
        hits = p.rayTestBatch([[x, y, 30.0]], [[x, y, -1.0]], physicsClientId=self.client)
        for hit in hits:
            if hit[0] >= 0:
                return float(hit[3][2])
        return 0.0

    def friction_at(self, x: float, y: float) -> float:
        """Friction coefficient of the terrain patch under (x, y); inf off every patch (the tyres' own decides)."""
        return self._friction(x, y)

    def object_category(self, body: int) -> str:
        """Category of the static object whose body id is `body` ('object' when unknown)."""
        i = self.object_index.get(body)
        return "object" if i is None else str(self.scene.objects[i].get("category", "object"))

    def close(self) -> None:
        """Disconnect from PyBullet when this world owns the client."""
        if self.owns_client and self.client is not None:
            try:
                p.disconnect(physicsClientId=self.client)
            except p.error:
                pass
            self.client = None


def sidewalk_solids(scene: Scene, h: float) -> tuple[list[list[Polygon]], list[tuple[np.ndarray, np.ndarray]]]:
    """The raised parts of a scene's sidewalks: per sidewalk (in `scene.sidewalks` order) its slabs (polygons from 0
    to the curb height `h`),
    and every curb ramp's wedges as (footprint vertices [k, 2], their heights [k]). The world builds these bodies
    and the grid LiDAR (sim.raycast.grids) rasterises the same solids."""
    cuts: dict[str, list[Polygon]] = {}
    sidewalks = {sw["id"]: sw for sw in scene.sidewalks}
    wedges: list[tuple[np.ndarray, np.ndarray]] = []
    for cw in scene.crosswalks:
        for ramp in cw.get("ramps", []):
            # Slightly grown, so no sliver of raised sidewalk survives between the ramp and the curb line.
            poly = Polygon(ramp["polygon"]).buffer(0.05, join_style="mitre")
            ramp_parts = ramp_wedges(scene, poly, sidewalks.get(ramp["sidewalk_id"]), h)
            wedges += ramp_parts
            cuts.setdefault(ramp["sidewalk_id"], []).extend(Polygon(pts) for pts, _ in ramp_parts)
    slabs: list[list[Polygon]] = []
    for sw in scene.sidewalks:
        geom = Polygon(sw["polygon"]).buffer(0)
        for cut in cuts.get(sw["id"], []):
            geom = geom.difference(cut.buffer(0.01, join_style="mitre"))
        # A sliver left by the ramp cut-outs is dropped: a wheel would catch on it.
        slabs.append([poly for poly in polygons(geom) if not poly.buffer(-0.05).is_empty])
    return slabs, wedges


def ramp_wedges(
    scene: Scene, poly: Polygon, sidewalk: Mapping[str, Any] | None, h: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """A curb ramp's wedges as (footprint vertices [k, 2], their heights [k]): the ramp, rising from the road (vertices
    on the curb line) to the sidewalk top `h`, and a sloped flare on each side (the grid LiDAR rasterises the same)."""
    pts = np.asarray(orient(poly, 1.0).exterior.coords)[:-1]
    if sidewalk is not None and len(sidewalk.get("edge", [])) >= 2:
        curb = LineString(sidewalk["edge"])
    else:
        curb = shapely.union_all([Polygon(road["polygon"]) for road in scene.roads]).boundary
    curb_dist = np.array([curb.distance(Point(x, y)) for x, y in pts])
    # The vertices on the curb line sit at road level; the rest rise to the sidewalk over the ramp.
    z = np.where(curb_dist < max(0.1, 0.25 * float(curb_dist.max())), 0.0, h)
    if z.max() == 0.0:
        z = np.full(len(pts), h)
    wedges = [(pts, z)]
    centre = pts.mean(0)
    num_pts = len(pts)
    for k in range(num_pts):
        start, end = k, (k + 1) % num_pts
        if z[start] == z[end]:
            continue
        lo, hi = (start, end) if z[start] < z[end] else (end, start)
        side = pts[hi] - pts[lo]
        out = np.array([side[1], -side[0]]) / max(np.hypot(*side), 1e-9)
        if np.dot(out, pts[lo] - centre) < 0:
            out = -out
        # A flare (sloped side) as curb ramps have: without it a wheel on the ramp meets a bare step.
        tri = np.array([pts[lo], pts[hi], pts[lo] + out * max(np.hypot(*side), 0.5)])
        wedges.append((tri, np.array([0.0, h, h])))
    return wedges
