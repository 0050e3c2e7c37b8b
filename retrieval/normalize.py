"""Mesh normalisation: load any trimesh format, quality filters, merge, upright, centre, front, units, PyBullet export.

Every refusal raises `AssetRejected(reason, detail)`; the ingest stage records it in the `rejections` table.
Reasons: corrupt_file, file_too_large, empty_mesh, nan_vertices, too_many_faces, missing_texture, bad_reference, degenerate.
"""

from __future__ import annotations

import json
import math
import os
import re
import stat
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
import trimesh
from trimesh.visual import ColorVisuals, TextureVisuals

if TYPE_CHECKING:
    from PIL import Image

MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".stl", ".ply")

# Formats whose specification (glTF) or common practice (OBJ from DCC tools) is y-up; STL/PLY are usually z-up.
FORMAT_UP_AXIS = {".glb": "+y", ".gltf": "+y", ".obj": "+y", ".stl": "+z", ".ply": "+z"}

# Rotations that take the named up axis onto +z (right-handed, so the front stays consistent).
_UP_ROTATIONS = {
    "+z": np.eye(3),
    "-z": np.diag([1.0, -1.0, -1.0]),
    "+y": np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]),
    "-y": np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]),
    "+x": np.array([[0, 0, -1.0], [0, 1.0, 0], [1.0, 0, 0]]),
    "-x": np.array([[0, 0, 1.0], [0, 1.0, 0], [-1.0, 0, 0]]),
}


class AssetRejected(Exception):
    """An asset that fails a quality filter; `reason` is a short code, `detail` says what was found."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail


@dataclass(frozen=True)
class QualityLimits:
    """Thresholds of the mesh quality filters."""

    max_faces: int = 500_000
    max_bytes: int = 200_000_000
    min_thickness_ratio: float = 0.004  # smallest/largest extent; below it the mesh is a sheet or a line


@dataclass
class CanonicalMesh:
    """A merged, upright mesh centred on x/y with its base at z = 0, and per-face RGBA colours."""

    mesh: trimesh.Trimesh
    face_colors: np.ndarray
    up_axis: str
    texture_image: Image.Image | None = None  # when the source carried a real UV texture
    uv: np.ndarray | None = None
    params: dict = field(default_factory=dict)

    @property
    def extents(self) -> np.ndarray:
        """Bounding-box extents (x, y, z) in the mesh's current units."""
        return self.mesh.extents


REFERENCE_MAX_BYTES = 64 * 2**20  # an MTL or glTF JSON an asset references; larger is not one


def read_reference(path: Path, max_bytes: int = REFERENCE_MAX_BYTES) -> str:
    """The text of a file an asset references (its MTL, its glTF JSON): a regular file of at most `max_bytes`, else
    AssetRejected("bad_reference"): a FIFO would block the reader, a device never end, a directory not read."""
    try:
        st = os.stat(path)
    except OSError as e:
        raise AssetRejected("bad_reference", f"{path.name}: {e.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise AssetRejected("bad_reference", f"{path.name} is not a regular file")
    if st.st_size > max_bytes:
        raise AssetRejected("bad_reference", f"{path.name} holds {st.st_size} bytes, more than {max_bytes}")
    try:
        return path.read_text(errors="replace")
    except OSError as e:
        raise AssetRejected("bad_reference", f"{path.name}: {e.strerror}") from None


def referenced_file(path: Path, name: str) -> Path | None:
    """The file `name` that `path` references, None when absent; AssetRejected when it exists but is no regular file."""
    ref = path.parent / name
    if not os.path.lexists(ref):
        return None
    if not ref.is_file():  # a FIFO, a device or a folder: the mesh loader would block on it or fail
        raise AssetRejected("bad_reference", f"{name} is not a regular file")
    return ref


def missing_textures(path: Path) -> list[str]:
    """Texture files that an OBJ's MTL or a glTF's JSON references but that do not exist next to it (AssetRejected
    "bad_reference" when one exists but is not a regular file, or is too large to be one)."""
    missing: list[str] = []
    suffix = path.suffix.lower()
    if suffix == ".obj":
        text = read_reference(path, max(REFERENCE_MAX_BYTES, path.stat().st_size))
        for mtl in re.findall(r"^\s*mtllib\s+(.+?)\s*$", text, flags=re.M):
            mtl_path = referenced_file(path, mtl)
            if mtl_path is None:
                missing.append(mtl)
                continue
            for tex in re.findall(r"^\s*map_Kd\s+(?:-\S+\s+\S+\s+)*(.+?)\s*$", read_reference(mtl_path), flags=re.M):
                if referenced_file(mtl_path, tex) is None:
                    missing.append(tex)
    elif suffix == ".gltf":
        try:
            doc = json.loads(read_reference(path))
        except (json.JSONDecodeError, UnicodeDecodeError):
            return []  # the loader reports it as corrupt
        for entry in doc.get("images", []) + doc.get("buffers", []):
            uri = entry.get("uri")
            if uri and not uri.startswith("data:") and referenced_file(path, uri) is None:
                missing.append(uri)
    return missing


def _texture(geom: trimesh.Trimesh) -> TextureVisuals | None:
    """The mesh's visuals when they are a texture, else None."""
    visual = geom.visual
    assert visual is not None  # the Trimesh constructor always sets one
    return cast(TextureVisuals, visual) if visual.kind == "texture" else None  # the only visuals of that kind


def _face_colors(geom: trimesh.Trimesh) -> np.ndarray:
    """Per-face RGBA, sampling textures at face centroids when the mesh is textured."""
    texture = _texture(geom)
    if texture is not None:
        try:
            return np.asarray(texture.to_color().face_colors, dtype=np.uint8)
        except Exception:  # noqa: BLE001 - a material without an image still has a main colour
            main = getattr(getattr(texture, "material", None), "main_color", None)
            color = np.asarray(main if main is not None else [180, 180, 180, 255], dtype=np.uint8)
            return np.tile(color, (len(geom.faces), 1))
    return np.asarray(cast(ColorVisuals, geom.visual).face_colors, dtype=np.uint8)  # a Trimesh's other visuals


def load_canonical(
    path: str | Path, *, up_axis: str | None = None, limits: QualityLimits | None = None
) -> CanonicalMesh:
    """Load a mesh file, apply the quality filters, merge the scene and make it upright, centred, front +x."""
    path = Path(path)
    limits = limits or QualityLimits()
    if not path.exists():
        raise AssetRejected("corrupt_file", f"{path} does not exist")
    size = path.stat().st_size
    if size > limits.max_bytes:
        raise AssetRejected("file_too_large", f"{size} bytes > max_bytes {limits.max_bytes}")
    missing = missing_textures(path)
    if missing:
        raise AssetRejected("missing_texture", f"referenced but absent: {', '.join(sorted(missing))}")
    try:
        # force="scene" makes load return a Scene, though it is typed as any Geometry
        loaded = cast(trimesh.Scene, trimesh.load(str(path), force="scene", process=False))
    except Exception as exc:  # noqa: BLE001 - any parser failure means the file is unusable
        raise AssetRejected("corrupt_file", f"{type(exc).__name__}: {exc}"[:300]) from None
    geoms = []
    for name in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[name]
        geom = loaded.geometry.get(geom_name)
        if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
            g = geom.copy()
            g.apply_transform(transform)
            geoms.append(g)
    n_faces = sum(len(g.faces) for g in geoms)
    if n_faces == 0:
        raise AssetRejected("empty_mesh", "no triangles in any geometry of the file")
    if n_faces > limits.max_faces:
        raise AssetRejected("too_many_faces", f"{n_faces} faces > max_faces {limits.max_faces}")
    for g in geoms:
        if not np.isfinite(g.vertices).all():
            raise AssetRejected(
                "nan_vertices", f"{int((~np.isfinite(g.vertices)).any(axis=1).sum())} vertices are NaN or inf"
            )

    texture_image, uv = None, None
    texture = _texture(geoms[0]) if len(geoms) == 1 else None
    if texture is not None:
        mat = getattr(texture, "material", None)
        img = getattr(mat, "baseColorTexture", None) or getattr(mat, "image", None)
        if img is not None and texture.uv is not None and len(texture.uv) == len(geoms[0].vertices):
            texture_image, uv = img, np.asarray(texture.uv, dtype=np.float64)
    colors = np.concatenate([_face_colors(g) for g in geoms])
    # concatenate is typed as returning any Geometry; given Trimeshes it returns a Trimesh
    mesh = cast(
        trimesh.Trimesh, trimesh.util.concatenate([trimesh.Trimesh(g.vertices, g.faces, process=False) for g in geoms])
    )

    up = up_axis or FORMAT_UP_AXIS.get(path.suffix.lower(), "+z")
    if up not in _UP_ROTATIONS:
        raise AssetRejected("corrupt_file", f"unknown up axis {up!r}; use one of {', '.join(_UP_ROTATIONS)}")
    rot = np.eye(4)
    rot[:3, :3] = _UP_ROTATIONS[up]
    mesh.apply_transform(rot)

    ext = mesh.extents
    if ext.max() <= 0 or not np.isfinite(ext).all() or mesh.area <= 0:
        raise AssetRejected("degenerate", f"extents {ext.tolist()}, area {mesh.area}")
    if ext.min() / ext.max() < limits.min_thickness_ratio:
        raise AssetRejected(
            "degenerate", f"thin: extents {np.round(ext, 6).tolist()} (ratio < {limits.min_thickness_ratio})"
        )

    # Front guess: street objects present their long side to the street, so the long horizontal extent goes on y
    # and the front (+x) faces across the short side.
    yaw = 0.0
    if ext[0] > ext[1] * 1.05:
        yaw = 90.0
        rz = trimesh.transformations.rotation_matrix(math.pi / 2, [0, 0, 1])
        mesh.apply_transform(rz)
    lo, hi = mesh.bounds
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return CanonicalMesh(
        mesh=mesh,
        face_colors=colors,
        up_axis=up,
        texture_image=texture_image,
        uv=uv,
        params={"up_axis_in": up, "yaw_deg": yaw, "face_count": int(n_faces)},
    )


def scale_mesh(canon: CanonicalMesh, scale: float) -> CanonicalMesh:
    """Return a copy scaled uniformly about the base centre (which stays at the origin)."""
    mesh = canon.mesh.copy()
    mesh.apply_scale(scale)
    return CanonicalMesh(mesh, canon.face_colors, canon.up_axis, canon.texture_image, canon.uv, dict(canon.params))


def export_obj(canon: CanonicalMesh, out_dir: str | Path, stem: str = "mesh") -> tuple[Path, Path, Path]:
    """Write OBJ + MTL + PNG texture that PyBullet's TinyRenderer shows with colour (it ignores vertex colours)."""
    from retrieval.procedural.export import palette_indices, palette_texture

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    obj_path, mtl_path, tex_path = out_dir / f"{stem}.obj", out_dir / f"{stem}.mtl", out_dir / f"{stem}.png"
    mesh = canon.mesh
    lines = [f"mtllib {mtl_path.name}", "usemtl baked"]
    verts: np.ndarray
    if canon.texture_image is not None and canon.uv is not None:
        canon.texture_image.convert("RGB").save(tex_path)
        verts, uvs, faces = mesh.vertices, canon.uv, mesh.faces + 1
        face_lines = [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in faces]
    else:
        # The same palette bake as the procedural library: one flat texture cell per distinct colour.
        colors, face_idx = palette_indices(canon.face_colors[:, :3])
        image, cell_uv = palette_texture(colors)
        image.save(tex_path)
        face_uv = cell_uv[face_idx]
        # Unmerged vertices: each face carries its own colour cell, so shared vertices cannot share a uv.
        verts = mesh.vertices[mesh.faces].reshape(-1, 3)
        uvs = np.repeat(face_uv, 3, axis=0)
        idx = np.arange(1, len(verts) + 1).reshape(-1, 3)
        face_lines = [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in idx]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts]
    lines += [f"vt {u:.6f} {v:.6f}" for u, v in uvs]
    lines += face_lines
    obj_path.write_text("\n".join(lines) + "\n")
    mtl_path.write_text(f"newmtl baked\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nmap_Kd {tex_path.name}\n")
    return obj_path, mtl_path, tex_path


def export_collision(canon: CanonicalMesh, out_dir: str | Path, stem: str = "collision") -> Path:
    """Write the convex hull as an OBJ for PyBullet's convex collision (box collision needs only the extents)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    hull = canon.mesh.convex_hull
    path = out_dir / f"{stem}.obj"
    hull.export(str(path), file_type="obj", include_normals=False, include_color=False, include_texture=False)
    return path


def export_glb(canon: CanonicalMesh, out_dir: str | Path, stem: str = "mesh") -> Path:
    """Write a GLB with face colours (z-up, metres, as stored in the catalog) for viewers and other engines."""
    out_dir = Path(out_dir)
    mesh = canon.mesh.copy()
    mesh.visual = trimesh.visual.ColorVisuals(mesh, face_colors=canon.face_colors)
    path = out_dir / f"{stem}.glb"
    mesh.export(str(path), file_type="glb")
    return path
