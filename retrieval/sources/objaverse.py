"""`objaverse`: Objaverse 1.0 (annotations, LVIS categories, GLBs) in the `objaverse` package's cache layout.

Files live under `cache_dir/hf-objaverse-v1` (object-paths.json.gz, metadata/<shard>.json.gz,
lvis-annotations.json.gz, glbs/<shard>/<uid>.glb), the layout of the `objaverse` package, so a cache it filled is
used as is. Every download (annotations too) has a socket timeout and retries, and goes to a temporary file renamed
into place (`os.replace`) only when complete: an interrupted run never leaves a truncated file that later reads
as data. Prefilters run on the annotations before any GLB download (licence, face count, GLB size); what they
refuse becomes an item carrying its rejection, so the stage records it. A GLB already in the cache is not fetched
again, so an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import gzip
import http.client
import json
import os
import socket
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from retrieval.sources import SourceCacheCorrupt, SourceItem, SourceUnavailable

HF_URL = "https://huggingface.co/datasets/allenai/objaverse/resolve/main"
URL_ENV = "CURBSIDE_OBJAVERSE_URL"  # another mirror (or, in tests, an address that refuses connections)
DEFAULT_CACHE = Path.home() / ".objaverse"

# LVIS category -> curbside category, for the LVIS categories that are street objects of one category.
LVIS_TO_CATEGORY = {
    "bench": "bench",
    "trash_can": "trash_bin",
    "dumpster": "trash_bin",
    "fireplug": "fire_hydrant",
    "traffic_light": "traffic_light",
    "parking_meter": "parking_meter",
    "mailbox_(at_home)": "mailbox",
    "postbox_(public)": "mailbox",
    "street_sign": "traffic_sign",
    "stop_sign": "traffic_sign",
    "streetlight": "street_lamp",
    "lamppost": "street_lamp",
    "bicycle": "bicycle",
    "cone": "traffic_cone",
    "shopping_bag": "shopping_bag",
    "carton": "cardboard_box",
    "can": "drink_can",
    "soda_can": "drink_can",
    "beer_can": "drink_can",
    "chair": "chair",
    "vending_machine": "vending_machine",
    "telephone_booth": "phone_booth",
    "flowerpot": "planter",
    "kiosk": "kiosk",
    "telephone_pole": "utility_pole",
    "signboard": "advertising_board",
    "billboard": "advertising_board",
    "water_fountain": "drinking_fountain",
    "newsstand": "newspaper_box",
    "cafe_table": "cafe_table",
    "table": "cafe_table",
    "scooter": "e_scooter",
    "pushcart": "food_cart",
    "barrel": "barrier",
    "cart": "food_cart",
}
# LVIS categories of street objects that name no single curbside category (a pole may be a bollard, a street
# lamp or a utility pole; a statue is none of the 33): their items carry no category, so the scorer decides, and
# an asset that matches only open-vocabulary descriptions of the pool is kept as an open-vocabulary asset.
LVIS_SCORED = ("pole", "statue_(sculpture)", "sculpture", "flagpole", "milestone", "parasol", "birdbath")
# Sketchfab licence codes in the annotations; the default keeps those that allow redistribution with attribution.
DEFAULT_LICENSES = ("by", "by-sa", "cc0")
LICENSE_NAMES = {
    "by": "CC-BY-4.0",
    "by-sa": "CC-BY-SA-4.0",
    "by-nd": "CC-BY-ND-4.0",
    "by-nc": "CC-BY-NC-4.0",
    "by-nc-sa": "CC-BY-NC-SA-4.0",
    "by-nc-nd": "CC-BY-NC-ND-4.0",
    "cc0": "CC0-1.0",
}


class DownloadError(OSError):
    """A download that failed after every retry (the last error is in the message)."""


def download(url: str, dest: Path, *, timeout: float = 60.0, retries: int = 3) -> Path:
    """Fetch `url` into `dest` atomically (temporary file, then os.replace), with a timeout and retries."""
    dest.parent.mkdir(parents=True, exist_ok=True)
    # One temporary name per process: two runs filling one cache never write the same file.
    tmp = dest.with_name(f".{dest.name}.{os.getpid()}.part")
    last: BaseException | None = None
    for attempt in range(max(1, retries)):
        try:
            with urllib.request.urlopen(url, timeout=timeout) as resp, open(tmp, "wb") as fh:
                expected = resp.headers.get("Content-Length")
                got = 0
                while chunk := resp.read(1 << 20):
                    fh.write(chunk)
                    got += len(chunk)
            # A connection closed early just ends the stream: only the announced length tells a short file.
            if expected is not None and got != int(expected):
                raise http.client.IncompleteRead(b"", int(expected) - got)
            os.replace(tmp, dest)
            return dest
        except (OSError, http.client.HTTPException) as exc:  # URLError, HTTPError, timeouts, resets, short reads
            last = exc
            tmp.unlink(missing_ok=True)
            if isinstance(getattr(exc, "reason", None), socket.gaierror):
                break  # the host name does not resolve: offline, and retrying will not change that
            if isinstance(exc, urllib.error.HTTPError) and 400 <= exc.code < 500:
                break  # the file is not there (404) or not ours to fetch: asking again will not change it
            if attempt + 1 < retries:
                time.sleep(min(2**attempt, 10))
        except BaseException:
            tmp.unlink(missing_ok=True)  # interrupted: no half file left behind
            raise
    reason = last if isinstance(last, urllib.error.HTTPError) else (getattr(last, "reason", None) or last)
    raise DownloadError(f"{url}: {type(last).__name__}: {reason}")


class ObjaverseCache:
    """The objaverse cache folder: reads files from it, downloading what is missing."""

    def __init__(
        self, root: str | Path | None = None, *, timeout: float = 60.0, retries: int = 3, base_url: str | None = None
    ) -> None:
        self.root = Path(root) if root is not None else DEFAULT_CACHE
        self.base = self.root / "hf-objaverse-v1"
        self.url = (base_url or os.environ.get(URL_ENV) or HF_URL).rstrip("/")
        self.timeout, self.retries = timeout, retries

    def file(self, rel: str) -> Path:
        """Local path of `rel` (e.g. glbs/000-000/uid.glb), downloaded first when missing; raises DownloadError."""
        local = self.base / rel
        if not local.exists():
            download(f"{self.url}/{rel}", local, timeout=self.timeout, retries=self.retries)
        return local

    def annotation(self, rel: str) -> Any:
        """A gzipped JSON annotation file; one line naming the problem and the fix when it cannot be had."""
        try:
            path = self.file(rel)
        except DownloadError as exc:
            raise SourceUnavailable(
                f"objaverse needs network access to download {rel} into {self.base} ({exc}); connect to the "
                f"network, pass --objaverse-cache DIR holding a filled cache, or ingest local meshes with "
                f"--source local:DIR"
            ) from None
        try:
            with gzip.open(path, "rt", encoding="utf-8") as fh:
                return json.load(fh)
        except (EOFError, OSError, ValueError) as exc:  # truncated gzip, not gzip, bad JSON or UTF-8
            raise SourceCacheCorrupt(
                f"objaverse cache file {path} is truncated or corrupt ({type(exc).__name__}: {exc}); delete it "
                f"and rerun to download it again"
            ) from None


class ObjaverseSource:
    """Objaverse objects of the street-object LVIS categories, prefiltered on their annotations."""

    name = "objaverse"

    def __init__(
        self,
        cache_dir: str | Path | None = None,
        lvis_categories: list[str] | None = None,
        licenses: tuple[str, ...] = DEFAULT_LICENSES,
        max_faces: int = 200_000,
        max_bytes: int = 50_000_000,
        timeout: float = 60.0,
        retries: int = 3,
        batch: int = 16,
        base_url: str | None = None,
        **_: object,
    ) -> None:
        self.cache = ObjaverseCache(cache_dir, timeout=timeout, retries=retries, base_url=base_url)
        chosen = [*LVIS_TO_CATEGORY, *LVIS_SCORED] if lvis_categories is None else list(lvis_categories)
        self.lvis = {k: LVIS_TO_CATEGORY.get(k) for k in chosen}
        self.licenses = tuple(licenses)
        self.max_faces, self.max_bytes = max_faces, max_bytes
        self.timeout, self.retries, self.batch = timeout, retries, batch
        self._paths: dict[str, str] | None = None

    def _object_paths(self) -> dict[str, str]:
        """uid -> path of its GLB in the repository (object-paths.json.gz, loaded once)."""
        if self._paths is None:
            self._paths = self.cache.annotation("object-paths.json.gz")
        return self._paths

    def _annotations(self, uids: list[str]) -> dict[str, dict]:
        """Sketchfab metadata of `uids`, from the metadata shards that hold them."""
        paths = self._object_paths()
        out: dict[str, dict] = {}
        for shard in sorted({paths[u].split("/")[1] for u in uids if u in paths}):
            data = self.cache.annotation(f"metadata/{shard}.json.gz")
            out.update({u: data[u] for u in uids if u in data})
        return out

    def _download(self, uids: list[str]) -> tuple[dict[str, str], dict[str, str]]:
        """Paths of the GLBs (downloading what is missing) and an error per uid that could not be fetched."""
        paths: dict[str, str] = {}
        errors: dict[str, str] = {}
        repo_paths = self._object_paths()
        for uid in uids:
            if uid not in repo_paths:
                errors[uid] = "uid not listed in object-paths.json.gz"
                continue
            try:
                paths[uid] = str(self.cache.file(repo_paths[uid]))
            except DownloadError as exc:  # this asset only: recorded as download_failed, retried next run
                errors[uid] = str(exc)[:200]
        return paths, errors

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        """Yield items category by category (uids sorted), prefiltered, downloading in batches."""
        lvis = self.cache.annotation("lvis-annotations.json.gz")
        chosen: list[tuple[str, str, str | None]] = []
        for lvis_cat in sorted(self.lvis):
            for uid in sorted(lvis.get(lvis_cat, [])):
                chosen.append((uid, lvis_cat, self.lvis[lvis_cat]))
        if limit is not None:
            chosen = chosen[:limit]
        for start in range(0, len(chosen), self.batch):
            part = chosen[start : start + self.batch]
            ann = self._annotations([u for u, _, _ in part])
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
                lic = a.get("license")
                verdict = verdicts.get(uid) or (("download_failed", errors[uid]) if uid in errors else None)
                tags = [t.get("name", "") for t in a.get("tags", [])][:20]
                yield SourceItem(
                    source="objaverse",
                    source_id=uid,
                    path=paths.get(uid, ""),
                    name=a.get("name", ""),
                    description=(a.get("description") or "").strip()[:500] or None,
                    # The LVIS name is a human label too: it tells the text signal what an uncategorised item is.
                    tags=tags if cat else [*tags, lvis_label(lvis_cat)],
                    category=cat,
                    license=LICENSE_NAMES.get(lic, lic) if lic else "unknown",
                    attribution=attribution(a, uid),
                    metadata={
                        "lvis": lvis_cat,
                        **provenance(a, uid),
                        **({"rejected": list(verdict)} if verdict else {}),
                    },
                )


def lvis_label(lvis_category: str) -> str:
    """An LVIS category as words: 'statue_(sculpture)' -> 'statue (sculpture)'."""
    return lvis_category.replace("_", " ")


def attribution(annotation: dict, uid: str) -> str:
    """'<name> by <author> (<Sketchfab URL>)', the attribution CC-BY asks for, from a Sketchfab annotation."""
    user = annotation.get("user") or {}
    author = user.get("displayName") or user.get("username") or "unknown author"
    url = annotation.get("viewerUrl") or f"https://sketchfab.com/3d-models/{uid}"
    return f"{annotation.get('name') or uid} by {author} ({url})"


def provenance(annotation: dict, uid: str) -> dict[str, str | None]:
    """What the catalog keeps about where an asset came from: licence code, author and its page, model page."""
    user = annotation.get("user") or {}
    return {
        "license_code": annotation.get("license"),
        "author": user.get("displayName") or user.get("username"),
        "author_url": user.get("profileUrl"),
        "source_url": annotation.get("viewerUrl") or f"https://sketchfab.com/3d-models/{uid}",
    }
