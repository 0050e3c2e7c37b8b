"""`procedural`: curbside's own parametric street objects (offline default), `per_category` seeded variants each.

Uses `retrieval.procedural` (generate/export_asset) when it is installed; until then a primitive stand-in of the
prior's size keeps the pipeline runnable (marked `generator: primitive` in the item's metadata).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from retrieval.sources import SourceItem

PROCEDURAL_LICENSE = "CC0-1.0"
PROCEDURAL_ATTRIBUTION = "curbside procedural library"


def _library():  # noqa: ANN202 - the procedural module, or None when it is not available
    try:
        from retrieval import procedural

        if hasattr(procedural, "generate") and hasattr(procedural, "export_asset"):
            return procedural
    except ImportError:
        pass
    return None


def _primitive(category: str, seed: int, out: Path) -> Path:
    """A coloured box/cylinder of the category's prior size (stand-in when the library is unavailable)."""
    import numpy as np
    import trimesh

    from retrieval.curation import load_size_priors

    prior = load_size_priors()[category]
    rng = np.random.default_rng(seed)
    h = rng.uniform(prior.height[0], prior.height[1])
    w = rng.uniform(prior.width[0], prior.width[1])
    d = rng.uniform(prior.depth[0], prior.depth[1])
    if w / max(d, 1e-6) < 1.3 and d / max(w, 1e-6) < 1.3:
        mesh = trimesh.creation.cylinder(radius=(w + d) / 4, height=h, sections=24)
    else:
        mesh = trimesh.creation.box([d, w, h])
    mesh.apply_translation([0, 0, h / 2])
    mesh.visual.face_colors = list(rng.integers(40, 220, 3)) + [255]
    path = out / f"{category}-{seed:04d}.ply"
    mesh.export(str(path))
    return path


class ProceduralSource:
    """Seeded variants of every (or the chosen) procedural category, exported as meshes into `work_dir`."""

    name = "procedural"

    def __init__(self, per_category: int = 2, categories: list[str] | None = None, seed: int = 0,
                 work_dir: str | Path | None = None, **_: object) -> None:
        from retrieval.curation import load_size_priors

        known = sorted(load_size_priors())
        lib = _library()
        if lib is not None:
            known = list(lib.category_names())
        self.categories = list(categories) if categories else known
        bad = [c for c in self.categories if c not in known]
        if bad:
            raise ValueError(f"unknown procedural categories {bad}; valid: {', '.join(known)}")
        self.per_category = per_category
        self.seed = seed
        self.work_dir = Path(work_dir) if work_dir else Path(".cache/curbside/procedural_source")

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        """Yield assets round-robin over categories so a small `limit` still covers many categories."""
        lib = _library()
        n = 0
        for k in range(self.per_category):
            for cat in self.categories:
                if limit is not None and n >= limit:
                    return
                seed = self.seed + k
                out = self.work_dir / f"{cat}-{seed:04d}"
                out.mkdir(parents=True, exist_ok=True)
                if lib is not None:
                    asset = lib.generate(cat, seed)
                    exported = lib.export_asset(asset, out)
                    path = Path(exported.obj_path)
                    desc = getattr(asset, "description", None)
                    syn = list(getattr(asset, "synonyms", []) or [])
                    companions = [str(p) for p in (exported.mtl_path, exported.texture_path) if p]
                    gen = "library"
                else:
                    path = _primitive(cat, seed, out)
                    desc, syn, companions, gen = None, [], [], "primitive"
                n += 1
                yield SourceItem(
                    source="procedural", source_id=f"{cat}-{seed:04d}", path=str(path),
                    name=cat.replace("_", " "), description=desc, tags=syn, category=cat,
                    license=PROCEDURAL_LICENSE, attribution=PROCEDURAL_ATTRIBUTION, up_axis="+z",
                    metadata={"companion_files": companions, "generator": gen, "seed": seed},
                )
