"""Asset sources behind one interface: `objaverse`, `objaverse-xl`, `local:DIR` and `procedural` yield `SourceItem`s.

A source lists candidate assets with their metadata (name, tags, licence, ...) and makes each one available as
a local mesh file; everything after that (normalisation, rendering, scoring, curation) is source-agnostic.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from kernel.config import ConfigError


@dataclass
class SourceItem:
    """One candidate asset: where its mesh file is and what the source says about it."""

    source: str
    source_id: str
    path: str
    name: str = ""
    description: str | None = None
    tags: list[str] = field(default_factory=list)
    category: str | None = None  # a trusted label (procedural category, LVIS category, sidecar), else None
    license: str = "unknown"
    attribution: str | None = None
    up_axis: str | None = None  # None: guessed from the file format's convention
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def metadata_text(self) -> str:
        """The free text the source gives about the asset, for metadata-text similarity."""
        parts = [self.name, self.description or "", " ".join(self.tags)]
        return ". ".join(p.strip() for p in parts if p and p.strip())

    def content_hash(self) -> str:
        """sha256 of the mesh file and every file next to it that it references (MTL, textures, sidecar)."""
        h = hashlib.sha256()
        h.update(f"{self.source}:{self.source_id}".encode())
        files = [self.path, *sorted(self.metadata.get("companion_files", []))] if self.path else []
        for f in files:
            f = Path(f)
            if f.is_file():
                h.update(f.name.encode())
                with open(f, "rb") as fh:
                    for chunk in iter(lambda: fh.read(1 << 20), b""):
                        h.update(chunk)
        return h.hexdigest()


class SourceError(RuntimeError):
    """A source that cannot list its assets at all (unlike a bad asset, which becomes a rejection)."""


class SourceUnavailable(SourceError):
    """The source needs something this machine lacks (network access to its index): the message says what to do."""


class SourceCacheCorrupt(SourceError):
    """A file in the source's local cache is truncated or damaged: the message names it and says to delete it."""


class Source(Protocol):
    """What every source provides."""

    name: str

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        """Yield candidate assets (at most `limit`), in a deterministic order."""
        ...


def open_source(spec: str, **options: Any) -> Source:
    """Open a source from its CLI spelling: `objaverse`, `objaverse-xl[:SOURCES]`, `local:DIR` or `procedural`."""
    if spec == "procedural":
        from retrieval.sources.procedural import ProceduralSource

        return ProceduralSource(**options)
    if spec == "objaverse":
        from retrieval.sources.objaverse import ObjaverseSource

        return ObjaverseSource(**options)
    if spec == "objaverse-xl" or spec.startswith("objaverse-xl:"):
        from retrieval.sources.objaverse_xl import XL_SOURCES, ObjaverseXLSource

        chosen = tuple(s.strip() for s in spec.split(":", 1)[1].split(",")) if ":" in spec else XL_SOURCES
        return ObjaverseXLSource(sources=chosen, **options)
    if spec.startswith("local:"):
        if not spec[len("local:") :].strip():
            raise ConfigError("--source local: needs a folder, as in local:path/to/meshes")
        from retrieval.sources.local import LocalSource

        return LocalSource(spec[len("local:") :], **options)
    raise ValueError(
        f"unknown source {spec!r}; use `objaverse`, `objaverse-xl[:smithsonian,thingiverse,sketchfab]`, "
        f"`local:DIR` or `procedural`"
    )
