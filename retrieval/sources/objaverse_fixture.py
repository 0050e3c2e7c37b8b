"""A small Objaverse cache built locally, in the exact layout of the `objaverse` package (0.1.x) and Objaverse-XL.

`build_objaverse_cache(root)` writes, under `root` (what `--objaverse-cache` takes, the package's BASE_PATH):

    hf-objaverse-v1/object-paths.json.gz        uid -> "glbs/<shard>/<uid>.glb"
    hf-objaverse-v1/metadata/<shard>.json.gz    uid -> Sketchfab annotation (name, tags, license, user, ...)
    hf-objaverse-v1/lvis-annotations.json.gz    LVIS category -> [uid, ...]
    hf-objaverse-v1/glbs/<shard>/<uid>.glb      the meshes (y-up GLB, as Objaverse ships them)
    smithsonian/smithsonian.parquet             Objaverse-XL annotations (with `xl=True`)
    smithsonian/objects/<uuid5(url)>.glb        ... and the objects the XL downloader stores
    thingiverse/thingiverse.parquet, thingiverse/thing-<t>-file-<f>.stl

The meshes are trimesh primitives (a bench, a bin, a lamp post, a bollard, a statue outside the 33 categories),
plus a GLB that is not one (rejected as corrupt_file) and a non-commercial model (rejected on its licence before
any download). Everything is deterministic: the same call writes the same bytes. Building takes well under a
second, so tests build it instead of committing binaries.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
import trimesh
from trimesh.visual import ColorVisuals

VERSIONED = "hf-objaverse-v1"


@dataclass(frozen=True)
class FixtureObject:
    """One Sketchfab object of the fixture: its LVIS category, licence code and mesh builder name."""

    key: str
    lvis: str | None
    license: str
    name: str
    tags: tuple[str, ...]
    shard: str


# key, LVIS category (None: not in LVIS), licence code, Sketchfab name, tags, metadata shard
OBJECTS = (
    FixtureObject("bench", "bench", "by", "Wooden park bench", ("bench", "park", "street furniture"), "000-000"),
    FixtureObject("bin", "trash_can", "cc0", "Green street litter bin", ("trash", "bin", "litter"), "000-000"),
    FixtureObject("lamp", "lamppost", "by-sa", "Old town lamp post", ("lamp", "streetlight", "lamppost"), "000-001"),
    FixtureObject("bollard", "pole", "by", "Steel traffic bollard", ("bollard", "barrier", "street"), "000-001"),
    FixtureObject(
        "statue",
        "statue_(sculpture)",
        "by",
        "Bronze statue on a plinth",
        ("statue", "sculpture", "monument"),
        "000-001",
    ),
    FixtureObject("broken", "bench", "by", "Bench (corrupt upload)", ("bench",), "000-000"),
    FixtureObject("nc", "bench", "by-nc", "Bench, non-commercial", ("bench",), "000-000"),
)


def fixture_uid(key: str) -> str:
    """The fixture object's uid: 32 hex digits like Objaverse's, stable across runs."""
    return hashlib.md5(f"curbside-fixture-{key}".encode()).hexdigest()


def _coloured(mesh: trimesh.Trimesh, rgb: tuple[int, int, int]) -> trimesh.Trimesh:
    visual = cast(ColorVisuals, mesh.visual)  # the fixture's parts are trimesh.creation primitives, colour visuals
    visual.face_colors = [*rgb, 255]
    return mesh


def _at(mesh: trimesh.Trimesh, xyz: tuple[float, float, float]) -> trimesh.Trimesh:
    mesh.apply_translation(xyz)
    return mesh


def fixture_mesh(key: str) -> trimesh.Trimesh:
    """The z-up mesh (metres) of a fixture object, built from primitives."""
    box, cyl, sphere = trimesh.creation.box, trimesh.creation.cylinder, trimesh.creation.icosphere
    if key in ("bench", "broken", "nc"):
        parts = [
            _coloured(_at(box([0.6, 1.8, 0.1]), (0, 0, 0.45)), (150, 90, 40)),
            _coloured(_at(box([0.08, 1.8, 0.5]), (-0.28, 0, 0.75)), (120, 70, 30)),
        ]
        parts += [
            _coloured(_at(box([0.08, 0.08, 0.45]), (x, y, 0.225)), (40, 40, 40))
            for x in (-0.25, 0.25)
            for y in (-0.8, 0.8)
        ]
    elif key == "bin":
        parts = [
            _coloured(_at(cyl(radius=0.25, height=0.9, sections=24), (0, 0, 0.45)), (30, 120, 50)),
            _coloured(_at(cyl(radius=0.27, height=0.05, sections=24), (0, 0, 0.92)), (20, 20, 20)),
        ]
    elif key == "lamp":
        parts = [
            _coloured(_at(cyl(radius=0.06, height=4.0, sections=16), (0, 0, 2.0)), (30, 30, 30)),
            _coloured(_at(box([0.9, 0.12, 0.08]), (0.4, 0, 3.95)), (30, 30, 30)),
            _coloured(_at(box([0.4, 0.3, 0.15]), (0.8, 0, 3.85)), (250, 240, 180)),
        ]
    elif key == "bollard":
        parts = [
            _coloured(_at(cyl(radius=0.1, height=0.9, sections=20), (0, 0, 0.45)), (90, 90, 95)),
            _coloured(_at(sphere(subdivisions=2, radius=0.1), (0, 0, 0.9)), (90, 90, 95)),
            _coloured(_at(cyl(radius=0.105, height=0.08, sections=20), (0, 0, 0.7)), (230, 200, 20)),
        ]
    elif key == "statue":
        parts = [
            _coloured(_at(box([0.8, 0.8, 1.0]), (0, 0, 0.5)), (170, 170, 165)),
            _coloured(_at(cyl(radius=0.18, height=1.1, sections=16), (0, 0, 1.55)), (110, 80, 40)),
            _coloured(_at(sphere(subdivisions=2, radius=0.16), (0, 0, 2.25)), (110, 80, 40)),
        ]
    else:
        raise ValueError(f"unknown fixture object {key!r}; use one of {[o.key for o in OBJECTS]}")
    return cast(trimesh.Trimesh, trimesh.util.concatenate(parts))  # Trimeshes concatenate to one


def _glb_bytes(mesh: trimesh.Trimesh) -> bytes:
    """The mesh as a y-up GLB (glTF's convention), as Objaverse ships its models."""
    m = mesh.copy()
    m.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    return trimesh.Scene([m]).export(file_type="glb")


def _write_gz_json(path: Path, obj: object) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    # mtime=0: the gzip header carries no timestamp, so the cache is byte-for-byte reproducible.
    with open(path, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as gz:
        gz.write(json.dumps(obj, sort_keys=True).encode())


def sketchfab_annotation(obj: FixtureObject, glb_size: int, faces: int, vertices: int) -> dict:
    """A Sketchfab annotation with the fields (and nesting) of Objaverse 1.0's metadata shards."""
    uid = fixture_uid(obj.key)
    return {
        "uid": uid,
        "name": obj.name,
        "license": obj.license,
        "viewerUrl": f"https://sketchfab.com/3d-models/{uid}",
        "embedUrl": f"https://sketchfab.com/models/{uid}/embed",
        "publishedAt": "2021-06-01T12:00:00.000000",
        "createdAt": "2021-06-01T11:00:00.000000",
        "description": f"{obj.name}. Low-poly model for street scenes.",
        "isDownloadable": True,
        "faceCount": faces,
        "vertexCount": vertices,
        "animationCount": 0,
        "viewCount": 100,
        "likeCount": 3,
        "commentCount": 0,
        "staffpickedAt": None,
        "isAgeRestricted": False,
        "tags": [
            {"name": t, "slug": t.replace(" ", "-"), "uri": f"https://api.sketchfab.com/v3/tags/{t}"} for t in obj.tags
        ],
        "categories": [{"name": "Architecture", "slug": "architecture"}],
        "user": {
            "uid": "0" * 32,
            "username": "curbside-fixture",
            "displayName": "Curbside Fixture Maker",
            "profileUrl": "https://sketchfab.com/curbside-fixture",
            "account": "basic",
        },
        "archives": {
            "glb": {
                "size": glb_size,
                "type": "glb",
                "faceCount": faces,
                "vertexCount": vertices,
                "textureCount": 0,
                "textureMaxResolution": 0,
            }
        },
    }


def build_objaverse_cache(root: str | Path, *, xl: bool = False) -> Path:
    """Write the fixture cache under `root` (Objaverse 1.0, plus Objaverse-XL sources with `xl`); returns `root`."""
    root = Path(root)
    base = root / VERSIONED
    paths: dict[str, str] = {}
    shards: dict[str, dict] = {}
    lvis: dict[str, list[str]] = {}
    for obj in OBJECTS:
        uid = fixture_uid(obj.key)
        rel = f"glbs/{obj.shard}/{uid}.glb"
        mesh = fixture_mesh(obj.key)
        if obj.key == "broken":
            data = b"glTF\x02\x00\x00\x00" + b"\x00truncated upload" * 8  # a GLB header and nothing that parses
        else:
            data = _glb_bytes(mesh)
        (base / rel).parent.mkdir(parents=True, exist_ok=True)
        (base / rel).write_bytes(data)
        paths[uid] = rel
        shards.setdefault(obj.shard, {})[uid] = sketchfab_annotation(
            obj, len(data), len(mesh.faces), len(mesh.vertices)
        )
        if obj.lvis:
            lvis.setdefault(obj.lvis, []).append(uid)
    _write_gz_json(base / "object-paths.json.gz", paths)
    for shard, ann in shards.items():
        _write_gz_json(base / "metadata" / f"{shard}.json.gz", ann)
    _write_gz_json(base / "lvis-annotations.json.gz", {k: sorted(v) for k, v in sorted(lvis.items())})
    if xl:
        build_xl_sources(root)
    return root


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _write_parquet(rows: list[dict], path: Path) -> None:
    import pandas as pd

    from kernel.reproducible import write_frame

    write_frame(
        pd.DataFrame(rows, columns=["fileIdentifier", "source", "license", "fileType", "sha256", "metadata"]), path
    )


def build_xl_sources(root: str | Path) -> Path:
    """Objaverse-XL's Smithsonian and Thingiverse annotations and stored objects, in the XL downloaders' layout."""
    root = Path(root)
    # Smithsonian: a bollard GLB stored under its uuid5, and one listed object never downloaded (fetched on demand).
    smith = []
    for key, url, title, store in (
        (
            "bollard",
            "https://3d-api.si.edu/content/document/3d_package:fixture-bollard/bollard.glb",
            "Cast-iron bollard",
            True,
        ),
        ("bench", "https://3d-api.si.edu/content/document/3d_package:fixture-bench/bench.glb", "Park bench", False),
    ):
        data = _glb_bytes(fixture_mesh(key))
        if store:
            path = root / "smithsonian" / "objects" / f"{uuid.uuid5(uuid.NAMESPACE_DNS, url)}.glb"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        smith.append(
            {
                "fileIdentifier": url,
                "source": "smithsonian",
                "license": "CC0",
                "fileType": "glb",
                "sha256": _sha256(data),
                "metadata": json.dumps({"title": title, "unit_name": "NMAH"}),
            }
        )
    _write_parquet(smith, root / "smithsonian" / "smithsonian.parquet")
    # Thingiverse: STL files named thing-<thing id>-file-<file id>.stl; one licence that forbids redistribution.
    thing = []
    for thing_id, file_id, key, lic in (
        (1001, 2001, "bin", "Creative Commons - Attribution"),
        (1002, 2002, "lamp", "All Rights Reserved"),
    ):
        data = cast(bytes, fixture_mesh(key).export(file_type="stl"))  # binary STL
        path = root / "thingiverse" / f"thing-{thing_id}-file-{file_id}.stl"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        thing.append(
            {
                "fileIdentifier": f"https://www.thingiverse.com/thing:{thing_id}/files?fileId={file_id}",
                "source": "thingiverse",
                "license": lic,
                "fileType": "stl",
                "sha256": _sha256(data),
                "metadata": json.dumps({"name": f"thing {thing_id}"}),
            }
        )
    _write_parquet(thing, root / "thingiverse" / "thingiverse.parquet")
    return root
