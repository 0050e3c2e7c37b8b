"""`local:DIR`: every GLB, GLTF, OBJ, STL and PLY under a folder, with an optional metadata sidecar JSON.

Sidecar: `<file>.json` or `<stem>.json` next to the mesh, with any of the keys name, description, tags, category,
license, attribution, up_axis (e.g. "+y"). Without one the file name is the only metadata.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

from retrieval.normalize import MESH_SUFFIXES, REFERENCE_MAX_BYTES, AssetRejected, read_reference, referenced_file
from retrieval.sources import SourceItem

SIDECAR_KEYS = ("name", "description", "tags", "category", "license", "attribution", "up_axis")


def _companions(path: Path) -> tuple[list[str], str | None]:
    """Files an OBJ or glTF pulls in, so their content takes part in the content hash; and why the asset cannot be
    used (a reference that is no regular file, or too large), or None."""
    out: list[str] = []
    try:
        if path.suffix.lower() == ".obj":
            text = read_reference(path, max(REFERENCE_MAX_BYTES, path.stat().st_size))
            for mtl in re.findall(r"^\s*mtllib\s+(.+?)\s*$", text, flags=re.M):
                out.append(str(path.parent / mtl))
                m = referenced_file(path, mtl)
                if m is not None:
                    out += [
                        str(m.parent / t) for t in re.findall(r"^\s*map_Kd\s+(.+?)\s*$", read_reference(m), flags=re.M)
                    ]
        elif path.suffix.lower() == ".gltf":
            try:
                doc = json.loads(read_reference(path))
                out += [
                    str(path.parent / e["uri"])
                    for e in doc.get("images", []) + doc.get("buffers", [])
                    if e.get("uri") and not e["uri"].startswith("data:")
                ]
            except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, AttributeError):
                pass
    except AssetRejected as e:
        return out, e.detail
    return out, None


class LocalSource:
    """Meshes in a local folder (recursive), sorted by relative path."""

    name = "local"

    def __init__(self, root: str | Path, license: str = "unknown", **_: object) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise FileNotFoundError(f"local source folder {self.root} does not exist; pass --source local:EXISTING_DIR")
        self.default_license = license

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        """Yield one item per mesh file; a bad sidecar rejects its own asset only (reason `bad_metadata`)."""
        files = sorted(p for p in self.root.rglob("*") if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)
        for n, path in enumerate(files):
            if limit is not None and n >= limit:
                return
            sidecar = next(
                (c for c in (path.with_name(path.name + ".json"), path.with_suffix(".json")) if c.exists()), None
            )
            meta: dict = {}
            problem = None
            if sidecar is not None:
                meta, problem = read_sidecar(sidecar)
            rel = path.relative_to(self.root).as_posix()
            companions, bad_reference = _companions(path)
            companions += [str(sidecar)] if sidecar else []
            metadata = {"companion_files": companions, "format": path.suffix.lower()[1:]}
            if bad_reference:
                metadata["rejected"] = ["bad_reference", bad_reference]
            elif problem:
                # The sidecar is part of the content hash: fixing it changes the hash, so a re-run retries the asset.
                metadata["rejected"] = ["bad_metadata", problem]
            yield SourceItem(
                source="local",
                source_id=rel,
                path=str(path),
                name=meta.get("name") or re.sub(r"[_\-.]+", " ", path.stem).strip(),
                description=meta.get("description"),
                tags=list(meta.get("tags", [])),
                category=meta.get("category"),
                license=meta.get("license", self.default_license),
                attribution=meta.get("attribution"),
                up_axis=meta.get("up_axis"),
                metadata=metadata,
            )


def read_sidecar(path: Path) -> tuple[dict, str | None]:
    """The sidecar's metadata, or ({}, why it is unusable): bad JSON, not an object, unknown keys, wrong types."""
    try:
        meta = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        return {}, f"metadata sidecar {path} is not valid JSON ({exc}); fix or remove it"
    if not isinstance(meta, dict):
        return {}, f"metadata sidecar {path} holds a {type(meta).__name__}, not a JSON object; fix or remove it"
    unknown = sorted(set(meta) - set(SIDECAR_KEYS))
    if unknown:
        return {}, f"sidecar {path} has unknown keys {unknown}; valid: {', '.join(SIDECAR_KEYS)}"
    bad = [k for k in SIDECAR_KEYS if k in meta and k != "tags" and not isinstance(meta[k], (str, type(None)))]
    if bad:
        return {}, f"sidecar {path}: {', '.join(bad)} must be text, got {meta[bad[0]]!r}; fix or remove it"
    tags = meta.get("tags", [])
    if not (isinstance(tags, list) and all(isinstance(t, str) for t in tags)):
        return {}, f"sidecar {path}: tags must be a list of strings, got {tags!r}; fix or remove it"
    return meta, None
