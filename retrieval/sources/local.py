"""`local:DIR`: every GLB, GLTF, OBJ, STL and PLY under a folder, with an optional metadata sidecar JSON.

Sidecar: `<file>.json` or `<stem>.json` next to the mesh, with any of the keys name, description, tags, category,
license, attribution, up_axis (e.g. "+y"). Without one the file name is the only metadata.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

from retrieval.normalize import MESH_SUFFIXES
from retrieval.sources import SourceItem

SIDECAR_KEYS = ("name", "description", "tags", "category", "license", "attribution", "up_axis")


def _companions(path: Path) -> list[str]:
    """Files an OBJ or glTF pulls in, so their content takes part in the content hash."""
    out: list[str] = []
    if path.suffix.lower() == ".obj":
        for mtl in re.findall(r"^\s*mtllib\s+(.+?)\s*$", path.read_text(errors="replace"), flags=re.M):
            m = path.parent / mtl
            out.append(str(m))
            if m.exists():
                out += [str(m.parent / t) for t in re.findall(r"^\s*map_Kd\s+(.+?)\s*$", m.read_text(errors="replace"), flags=re.M)]
    elif path.suffix.lower() == ".gltf":
        try:
            doc = json.loads(path.read_text())
            out += [str(path.parent / e["uri"]) for e in doc.get("images", []) + doc.get("buffers", [])
                    if e.get("uri") and not e["uri"].startswith("data:")]
        except (json.JSONDecodeError, UnicodeDecodeError, KeyError):
            pass
    return out


class LocalSource:
    """Meshes in a local folder (recursive), sorted by relative path."""

    name = "local"

    def __init__(self, root: str | Path, license: str = "unknown", **_: object) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise FileNotFoundError(f"local source folder {self.root} does not exist; pass --source local:EXISTING_DIR")
        self.default_license = license

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        """Yield one item per mesh file."""
        files = sorted(p for p in self.root.rglob("*") if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)
        for n, path in enumerate(files):
            if limit is not None and n >= limit:
                return
            meta: dict = {}
            sidecar = None
            for cand in (path.with_name(path.name + ".json"), path.with_suffix(".json")):
                if cand.exists():
                    sidecar = cand
                    try:
                        meta = json.loads(cand.read_text())
                    except json.JSONDecodeError as exc:
                        raise ValueError(f"metadata sidecar {cand} is not valid JSON ({exc}); fix or remove it") from None
                    unknown = set(meta) - set(SIDECAR_KEYS)
                    if unknown:
                        raise ValueError(f"sidecar {cand} has unknown keys {sorted(unknown)}; valid: {', '.join(SIDECAR_KEYS)}")
                    break
            rel = path.relative_to(self.root).as_posix()
            companions = _companions(path) + ([str(sidecar)] if sidecar else [])
            yield SourceItem(
                source="local", source_id=rel, path=str(path),
                name=meta.get("name") or re.sub(r"[_\-.]+", " ", path.stem).strip(),
                description=meta.get("description"), tags=list(meta.get("tags", [])), category=meta.get("category"),
                license=meta.get("license", self.default_license), attribution=meta.get("attribution"),
                up_axis=meta.get("up_axis"), metadata={"companion_files": companions, "format": path.suffix.lower()[1:]},
            )
