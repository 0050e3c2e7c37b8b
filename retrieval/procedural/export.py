"""Export a ProceduralAsset: OBJ + MTL + palette texture (for PyBullet) and GLB, plus its catalog record.

PyBullet's TinyRenderer ignores vertex colours, so face colours are baked into a small palette texture: every
colour gets a flat 8x8 cell, and each face's three texture coordinates point at the centre of its cell.
"""

from __future__ import annotations

import hashlib
import io
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
import trimesh
from PIL import Image

from catalogs.layout import stored_path
from catalogs.records import AssetRecord
from retrieval.procedural.library import ProceduralAsset

CELL = 8  # texture pixels per palette cell; wide enough that bilinear filtering never mixes neighbours
GRID = 8  # cells per texture row


@dataclass(frozen=True)
class ExportedAsset:
    """Files written for one asset (absolute paths) and the sha256 of the OBJ bytes."""

    folder: Path
    obj_path: Path
    mtl_path: Path
    texture_path: Path
    glb_path: Path
    content_hash: str


def palette_indices(face_colors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct colours in order of first appearance, and each face's index into them."""
    uniq, first, inverse = np.unique(face_colors, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return uniq[order], rank[inverse.reshape(-1)]


def palette_texture(colors: np.ndarray) -> tuple[Image.Image, np.ndarray]:
    """Texture image with one flat cell per colour, and the (u, v) of each cell's centre (OBJ: v up)."""
    n = len(colors)
    rows = max(1, -(-n // GRID))
    img = np.full((rows * CELL, GRID * CELL, 3), 255, dtype=np.uint8)
    uv = np.zeros((n, 2))
    for i, c in enumerate(colors):
        r, col = divmod(i, GRID)
        img[r * CELL : (r + 1) * CELL, col * CELL : (col + 1) * CELL] = c[:3]
        uv[i] = ((col + 0.5) / GRID, 1.0 - (r + 0.5) / rows)
    return Image.fromarray(img, "RGB"), uv


def obj_text(mesh: trimesh.Trimesh, face_palette_index: np.ndarray, uv: np.ndarray, mtl_name: str) -> str:
    """Wavefront OBJ with flat per-face normals and one texture coordinate per palette colour."""
    normals = np.round(mesh.face_normals, 4) + 0.0  # + 0.0 turns -0.0 into 0.0 for stable bytes
    uniq_n, n_idx = np.unique(normals, axis=0, return_inverse=True)
    n_idx = n_idx.reshape(-1)
    out = io.StringIO()
    out.write(f"# curbside procedural asset\nmtllib {mtl_name}\no asset\n")
    out.writelines(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in mesh.vertices)
    out.writelines(f"vt {u:.6f} {v:.6f}\n" for u, v in uv)
    out.writelines(f"vn {x:.4f} {y:.4f} {z:.4f}\n" for x, y, z in uniq_n)
    out.write("usemtl palette\ns off\n")
    for f, t, n in zip(mesh.faces + 1, face_palette_index + 1, n_idx + 1):
        out.write(f"f {f[0]}/{t}/{n} {f[1]}/{t}/{n} {f[2]}/{t}/{n}\n")
    return out.getvalue()


def glb_bytes(asset: ProceduralAsset, colors: np.ndarray, face_palette_index: np.ndarray) -> bytes:
    """Binary glTF with one node per colour, each with a PBR base colour (glTF has no per-face colours)."""
    scene = trimesh.Scene()
    for i, c in enumerate(colors):
        faces = np.flatnonzero(face_palette_index == i)
        part = cast(trimesh.Trimesh, asset.mesh.submesh([faces], append=True))  # append=True: one mesh, not a list
        material = trimesh.visual.material.PBRMaterial(
            name=f"color_{i:02d}",
            baseColorFactor=np.asarray(c, dtype=np.uint8),
            metallicFactor=0.0,
            roughnessFactor=0.8,
        )
        part.visual = trimesh.visual.TextureVisuals(material=material)
        scene.add_geometry(part, geom_name=f"part_{i:02d}", node_name=f"part_{i:02d}")
    return scene.export(file_type="glb")


def export_asset(asset: ProceduralAsset, out_dir: Path) -> ExportedAsset:
    """Write model.obj, model.mtl, texture.png and model.glb into `out_dir` (deterministic bytes)."""
    folder = Path(out_dir)
    folder.mkdir(parents=True, exist_ok=True)
    colors, face_idx = palette_indices(asset.face_colors)
    image, uv = palette_texture(colors)
    obj = obj_text(asset.mesh, face_idx, uv, "model.mtl").encode()
    mtl = (
        b"newmtl palette\nKa 1.000 1.000 1.000\nKd 1.000 1.000 1.000\nKs 0.000 0.000 0.000\n"
        b"d 1.0\nillum 1\nmap_Kd texture.png\n"
    )
    paths = {name: folder / name for name in ("model.obj", "model.mtl", "texture.png", "model.glb")}
    paths["model.obj"].write_bytes(obj)
    paths["model.mtl"].write_bytes(mtl)
    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=False)
    paths["texture.png"].write_bytes(buf.getvalue())
    paths["model.glb"].write_bytes(glb_bytes(asset, colors, face_idx))
    return ExportedAsset(
        folder=folder,
        obj_path=paths["model.obj"],
        mtl_path=paths["model.mtl"],
        texture_path=paths["texture.png"],
        glb_path=paths["model.glb"],
        content_hash=hashlib.sha256(obj).hexdigest(),
    )


def pybullet_extents(obj_path: Path) -> np.ndarray:
    """Extents (x, y, z) of the OBJ as PyBullet loads it (visual + collision shape in a DIRECT client)."""
    from kernel.quiet import import_pybullet

    p = import_pybullet()

    cid = p.connect(p.DIRECT)
    try:
        vis = p.createVisualShape(p.GEOM_MESH, fileName=str(obj_path), physicsClientId=cid)
        col = p.createCollisionShape(p.GEOM_MESH, fileName=str(obj_path), physicsClientId=cid)
        if vis < 0 or col < 0:
            raise RuntimeError(f"PyBullet could not load {obj_path} (visual id {vis}, collision id {col})")
        body = p.createMultiBody(0.0, col, vis, physicsClientId=cid)
        # getAABB pads convex hulls by their collision margin (~2 mm a side, 7 % of a drink can), so measure the
        # loaded collision vertices instead.
        count, verts = p.getMeshData(body, physicsClientId=cid)
        if count == 0:
            raise RuntimeError(f"PyBullet loaded no vertices from {obj_path}")
        v = np.asarray(verts, dtype=float)
        return v.max(axis=0) - v.min(axis=0)
    finally:
        p.disconnect(cid)


def to_record(asset: ProceduralAsset, exported: ExportedAsset, catalog_dir: Path) -> AssetRecord:
    """The catalog row of an exported asset; file paths are stored relative to `catalog_dir` (posix)."""
    ident = f"{asset.category}/{asset.seed:04d}"
    return AssetRecord(
        asset_id=f"procedural/{ident}",
        source="procedural",
        source_id=ident,
        category=asset.category,
        object_class=asset.object_class,
        zones=list(asset.zones),
        depth=asset.dims[0],
        width=asset.dims[1],
        height=asset.dims[2],
        description=asset.description,
        synonyms=list(asset.synonyms),
        license="CC0-1.0",
        mass=asset.mass,
        color=asset.color,
        material=asset.material,
        attribution="generated by curbside",
        mesh_path=stored_path(exported.obj_path, catalog_dir),
        glb_path=stored_path(exported.glb_path, catalog_dir),
        collision="box",
        face_count=len(asset.mesh.faces),
        watertight=asset.watertight,
        content_hash=exported.content_hash,
        params=dict(asset.params),
    )
