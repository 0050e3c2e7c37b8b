"""Plain dataclasses for catalog rows, shared by the writer (pipelines) and the reader (simulator)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass
class AssetRecord:
    """One row of the `assets` table (see catalogs.schema for the axis and path conventions)."""

    asset_id: str
    source: str
    source_id: str
    category: str
    object_class: str
    zones: list[str]
    depth: float
    width: float
    height: float
    description: str
    synonyms: list[str]
    license: str
    mass: float | None = None
    up_axis: str = "+z"
    front_axis: str = "+x"
    color: str | None = None
    material: str | None = None
    attribution: str | None = None
    mesh_path: str | None = None
    glb_path: str | None = None
    collision: str = "box"
    collision_path: str | None = None
    face_count: int | None = None
    watertight: bool | None = None
    content_hash: str | None = None
    params: dict[str, Any] = field(default_factory=dict)

    def to_row(self) -> dict[str, Any]:
        """Return the record as a dict keyed by column name."""
        return asdict(self)

    @property
    def size(self) -> tuple[float, float, float]:
        """Extents (depth along x, width along y, height along z) in metres."""
        return (self.depth, self.width, self.height)


@dataclass
class ViewRecord:
    """One rendered view of an asset."""

    asset_id: str
    view_index: int
    azimuth: float
    elevation: float
    image_path: str
    informative: bool = False
    informativeness: float | None = None


@dataclass
class DescriptionRecord:
    """One entry of the description pool (a cluster of real-world object descriptions)."""

    description_id: str
    text: str
    category: str | None = None
    cluster_id: int | None = None
    members: list[str] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)
    country_counts: dict[str, int] = field(default_factory=dict)


@dataclass
class MatchRecord:
    """An asset matched to a description, with the scores and the scorer that produced them."""

    asset_id: str
    description_id: str
    score: float
    scorer: str
    image_score: float | None = None
    text_score: float | None = None
    rank: int | None = None


@dataclass
class RejectionRecord:
    """An asset a stage refused, with the reason (never silently dropped)."""

    source: str
    source_id: str
    stage: str
    reason: str
    detail: str | None = None
    # Hash of the ingest configuration that produced the rejection: a re-run under another configuration retries it.
    config_hash: str | None = None
