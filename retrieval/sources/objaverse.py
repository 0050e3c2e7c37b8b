"""`objaverse`: Objaverse 1.0 through the `objaverse` package (annotations, LVIS categories, GLBs in its cache).

The package keeps everything under `objaverse.BASE_PATH/hf-objaverse-v1` (object-paths.json.gz, metadata/
shards, lvis-annotations.json.gz, glbs/); `cache_dir` points it elsewhere. Prefilters run on the annotations
before any download (licence, face count, GLB size); what they refuse becomes an item carrying its rejection, so
the stage records it. Downloads go through `objaverse.load_objects` with a socket timeout and retries; a GLB
already in the cache is not fetched again, so an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path

from retrieval.sources import SourceItem

# LVIS category -> curbside category, for the LVIS categories that are street objects.
LVIS_TO_CATEGORY = {
    "bench": "bench", "trash_can": "trash_bin", "fireplug": "fire_hydrant", "traffic_light": "traffic_light",
    "parking_meter": "parking_meter", "mailbox_(at_home)": "mailbox", "postbox_(public)": "mailbox",
    "street_sign": "traffic_sign", "streetlight": "street_lamp", "bicycle": "bicycle", "cone": "traffic_cone",
    "shopping_bag": "shopping_bag", "carton": "cardboard_box", "can": "drink_can", "soda_can": "drink_can",
    "beer_can": "drink_can", "chair": "chair", "vending_machine": "vending_machine", "telephone_booth": "phone_booth",
    "flowerpot": "planter", "kiosk": "kiosk", "telephone_pole": "utility_pole", "signboard": "advertising_board",
    "billboard": "advertising_board", "water_fountain": "drinking_fountain", "newsstand": "newspaper_box",
    "cafe_table": "cafe_table", "table": "cafe_table", "scooter": "e_scooter", "pushcart": "food_cart",
    "barrel": "barrier", "bus_(vehicle)": None, "cart": "food_cart",
}
# Sketchfab licence codes in the annotations; the default keeps those that allow redistribution with attribution.
DEFAULT_LICENSES = ("by", "by-sa", "cc0")
LICENSE_NAMES = {"by": "CC-BY-4.0", "by-sa": "CC-BY-SA-4.0", "by-nd": "CC-BY-ND-4.0", "by-nc": "CC-BY-NC-4.0",
                 "by-nc-sa": "CC-BY-NC-SA-4.0", "by-nc-nd": "CC-BY-NC-ND-4.0", "cc0": "CC0-1.0"}


def use_cache_dir(cache_dir: str | Path) -> None:
    """Point the objaverse package at `cache_dir` (it reads these module paths at every call)."""
    import objaverse

    objaverse.BASE_PATH = str(cache_dir)
    objaverse._VERSIONED_PATH = str(Path(cache_dir) / "hf-objaverse-v1")


class ObjaverseSource:
    """Objaverse objects of the street-object LVIS categories, prefiltered on their annotations."""

    name = "objaverse"

    def __init__(self, cache_dir: str | Path | None = None, lvis_categories: list[str] | None = None,
                 licenses: tuple[str, ...] = DEFAULT_LICENSES, max_faces: int = 200_000,
                 max_bytes: int = 50_000_000, timeout: float = 60.0, retries: int = 3, batch: int = 16,
                 **_: object) -> None:
        if cache_dir is not None:
            use_cache_dir(cache_dir)
        self.lvis = {k: v for k, v in LVIS_TO_CATEGORY.items() if v} if lvis_categories is None else \
            {k: LVIS_TO_CATEGORY.get(k) for k in lvis_categories}
        self.licenses = tuple(licenses)
        self.max_faces, self.max_bytes = max_faces, max_bytes
        self.timeout, self.retries, self.batch = timeout, retries, batch

    def _download(self, uids: list[str]) -> tuple[dict[str, str], dict[str, str]]:
        """Paths of the GLBs (downloading what is missing) and an error per uid that could not be fetched."""
        import objaverse

        paths: dict[str, str] = {}
        errors: dict[str, str] = {}
        old = socket.getdefaulttimeout()
        socket.setdefaulttimeout(self.timeout)  # urllib.urlretrieve inside objaverse has no timeout of its own
        try:
            for uid in uids:
                for attempt in range(self.retries):
                    try:
                        paths.update(objaverse.load_objects([uid]))
                        errors.pop(uid, None)
                        break
                    except Exception as exc:  # noqa: BLE001 - network errors of every kind: retry, then record
                        errors[uid] = f"{type(exc).__name__}: {exc}"[:200]
                        time.sleep(min(2 ** attempt, 10) * (attempt + 1 < self.retries))
        finally:
            socket.setdefaulttimeout(old)
        return paths, errors

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        """Yield items category by category (uids sorted), prefiltered, downloading in batches."""
        import objaverse

        lvis = objaverse.load_lvis_annotations()
        chosen: list[tuple[str, str, str]] = []
        for lvis_cat in sorted(self.lvis):
            for uid in sorted(lvis.get(lvis_cat, [])):
                chosen.append((uid, lvis_cat, self.lvis[lvis_cat] or lvis_cat))
        if limit is not None:
            chosen = chosen[:limit]
        for start in range(0, len(chosen), self.batch):
            part = chosen[start:start + self.batch]
            ann = objaverse.load_annotations([u for u, _, _ in part])
            ok = []
            verdicts: dict[str, tuple[str, str]] = {}
            for uid, _, _ in part:
                a = ann.get(uid, {})
                lic = a.get("license")
                faces = a.get("faceCount") or a.get("archives", {}).get("glb", {}).get("faceCount")
                size = a.get("archives", {}).get("glb", {}).get("size")
                if lic not in self.licenses:
                    verdicts[uid] = ("license", f"licence {lic!r} not in {list(self.licenses)}")
                elif faces is not None and faces > self.max_faces:
                    verdicts[uid] = ("too_many_faces", f"annotated faceCount {faces} > {self.max_faces}")
                elif size is not None and size > self.max_bytes:
                    verdicts[uid] = ("file_too_large", f"annotated GLB size {size} > {self.max_bytes}")
                else:
                    ok.append(uid)
            paths, errors = self._download(ok)
            for uid, lvis_cat, cat in part:
                a = ann.get(uid, {})
                user = a.get("user", {}) or {}
                verdict = verdicts.get(uid) or (("download_failed", errors[uid]) if uid in errors else None)
                yield SourceItem(
                    source="objaverse", source_id=uid, path=paths.get(uid, ""), name=a.get("name", ""),
                    description=(a.get("description") or "").strip()[:500] or None,
                    tags=[t.get("name", "") for t in a.get("tags", [])][:20], category=cat,
                    license=LICENSE_NAMES.get(a.get("license"), a.get("license") or "unknown"),
                    attribution=f"{a.get('name', uid)} by {user.get('displayName') or user.get('username') or 'unknown'}"
                                f" ({a.get('viewerUrl') or 'https://sketchfab.com/3d-models/' + uid})",
                    metadata={"lvis": lvis_cat, **({"rejected": list(verdict)} if verdict else {})},
                )
