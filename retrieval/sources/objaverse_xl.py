"""`objaverse-xl[:SOURCES]`: Objaverse-XL objects (Smithsonian, Thingiverse, Sketchfab) in the XL package's layout.

Annotations are `<cache>/<source>/<source>.parquet` (columns fileIdentifier, source, license, fileType, sha256,
metadata), read with the `objaverse.xl` downloaders themselves once the file is in place (a missing one is
downloaded first with the same timeout, retries and atomic rename as the Objaverse 1.0 source). Objects live where
`objaverse.xl.download_objects` stores them: `smithsonian/objects/<uuid5(url)>.glb`,
`thingiverse/thing-<thing>-file-<file>.stl`, and for Sketchfab the Objaverse 1.0 cache (`hf-objaverse-v1`). A
missing object is fetched from its URL; one whose sha256 differs from the annotation is refused (the file changed
upstream). GitHub objects need a clone of their repository per object, which this source does not do: fill the
cache with `objaverse.xl.download_objects(..., save_repo_format="files")` and use `--source local:DIR`.
XL carries no LVIS labels: items have no category, the scorer files them (or keeps them as open vocabulary).
"""

from __future__ import annotations

import hashlib
import json
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from retrieval.sources import SourceCacheCorrupt, SourceItem, SourceUnavailable
from retrieval.sources.objaverse import DEFAULT_CACHE, DownloadError, ObjaverseCache, download

XL_URL = "https://huggingface.co/datasets/allenai/objaverse-xl/resolve/main"
XL_SOURCES = ("smithsonian", "thingiverse", "sketchfab")
# Licence strings of the XL annotations -> SPDX-style names; the default keeps those that allow redistribution.
XL_LICENSES = {
    "CC0": "CC0-1.0",
    "Public Domain": "public-domain",
    "Creative Commons - Public Domain Dedication": "CC0-1.0",
    "Creative Commons - Attribution": "CC-BY",
    "Creative Commons - Attribution - Share Alike": "CC-BY-SA",
    "by": "CC-BY-4.0",
    "by-sa": "CC-BY-SA-4.0",
    "cc0": "CC0-1.0",
    "Creative Commons - Attribution - Non-Commercial": "CC-BY-NC",
    "by-nc": "CC-BY-NC-4.0",
    "Creative Commons - Attribution - No Derivatives": "CC-BY-ND",
    "All Rights Reserved": "all-rights-reserved",
}
DEFAULT_XL_LICENSES = ("CC0-1.0", "public-domain", "CC-BY", "CC-BY-SA", "CC-BY-4.0", "CC-BY-SA-4.0")


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


class ObjaverseXLSource:
    """Objaverse-XL objects of the chosen XL sources, licence-filtered on the annotations before any download."""

    name = "objaverse-xl"

    def __init__(
        self,
        cache_dir: str | Path | None = None,
        sources: tuple[str, ...] = XL_SOURCES,
        licenses: tuple[str, ...] = DEFAULT_XL_LICENSES,
        timeout: float = 60.0,
        retries: int = 3,
        base_url: str | None = None,
        **_: object,
    ) -> None:
        unknown = sorted(set(sources) - set(XL_SOURCES))
        if "github" in unknown:
            raise ValueError(
                "objaverse-xl:github is not supported (each object needs its repository cloned); fetch "
                "them with objaverse.xl.download_objects(save_repo_format='files') and use --source "
                "local:DIR"
            )
        if unknown or not sources:
            raise ValueError(
                f"unknown Objaverse-XL source(s) {unknown}; use some of {', '.join(XL_SOURCES)}, e.g. "
                f"--source objaverse-xl:smithsonian,thingiverse"
            )
        self.root = Path(cache_dir) if cache_dir is not None else DEFAULT_CACHE
        self.sources = tuple(s for s in XL_SOURCES if s in sources)
        self.licenses = tuple(licenses)
        self.timeout, self.retries = timeout, retries
        self.url = (base_url or XL_URL).rstrip("/")
        self.sketchfab = ObjaverseCache(self.root, timeout=timeout, retries=retries)

    def annotations(self, source: str) -> Any:
        """The XL annotations of one source as the `objaverse.xl` downloader reads them (a DataFrame)."""
        from objaverse.xl import downloaders

        path = self.root / source / f"{source}.parquet"
        if not path.exists():
            try:
                download(f"{self.url}/{source}/{source}.parquet", path, timeout=self.timeout, retries=self.retries)
            except DownloadError as exc:
                raise SourceUnavailable(
                    f"objaverse-xl needs network access to download {source}/{source}.parquet into {self.root} "
                    f"({exc}); connect to the network, pass --objaverse-cache DIR holding a filled cache, or "
                    f"ingest local meshes with --source local:DIR"
                ) from None
        try:
            return downloaders[source].get_annotations(download_dir=str(self.root))
        except (OSError, ValueError) as exc:  # pyarrow's ArrowInvalid is a ValueError
            raise SourceCacheCorrupt(
                f"objaverse-xl cache file {path} is truncated or corrupt ({type(exc).__name__}: "
                f"{exc}); delete it and rerun to download it again"
            ) from None

    def _local(self, source: str, ident: str) -> tuple[Path, str | None]:
        """Where the XL downloader stores the object, and the URL to fetch it from (None: via the 1.0 cache)."""
        if source == "smithsonian":
            return self.root / "smithsonian" / "objects" / f"{uuid.uuid5(uuid.NAMESPACE_DNS, ident)}.glb", ident
        if source == "thingiverse":
            thing, file_id = ident.split("/")[-2].split(":")[1], ident.split("fileId=")[-1]
            return (
                self.root / "thingiverse" / f"thing-{thing}-file-{file_id}.stl",
                f"https://www.thingiverse.com/download:{file_id}",
            )
        uid = ident.rstrip("/").split("/")[-1]
        return self.sketchfab.base / self.sketchfab.annotation("object-paths.json.gz").get(uid, f"glbs/{uid}.glb"), None

    def _fetch(self, source: str, ident: str, sha256: str) -> tuple[str, tuple[str, str] | None]:
        """The object's local path, or a rejection (download_failed) when it cannot be had or its bytes changed."""
        path, url = self._local(source, ident)
        try:
            if not path.exists():
                if url is None:
                    path = self.sketchfab.file(str(path.relative_to(self.sketchfab.base)))
                else:
                    download(url, path, timeout=self.timeout, retries=self.retries)
        except DownloadError as exc:
            return "", ("download_failed", str(exc)[:200])
        if sha256 and _sha256(path) != sha256:
            why = (
                f"sha256 of {path.name} differs from the Objaverse-XL annotation (the file changed upstream); "
                f"delete it to fetch it again"
            )
            return str(path), ("download_failed", why)
        return str(path), None

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        """Yield items source by source, sorted by file identifier; licences are checked before any download."""
        n = 0
        for source in self.sources:
            df = self.annotations(source).sort_values("fileIdentifier", kind="stable")
            for row in df.to_dict("records"):
                if limit is not None and n >= limit:
                    return
                n += 1
                ident = str(row["fileIdentifier"])
                meta = row.get("metadata")
                meta = json.loads(meta) if isinstance(meta, str) and meta else (meta or {})
                licence = XL_LICENSES.get(str(row.get("license")), str(row.get("license") or "unknown"))
                verdict = None
                path = ""
                if licence not in self.licenses:
                    verdict = ("license", f"licence {row.get('license')!r} ({licence}) not in {list(self.licenses)}")
                else:
                    path, verdict = self._fetch(source, ident, str(row.get("sha256") or ""))
                title = str(meta.get("title") or meta.get("name") or Path(ident.split("?")[0]).stem)
                holder = {
                    "smithsonian": "the Smithsonian Institution",
                    "thingiverse": "a Thingiverse author",
                    "sketchfab": "a Sketchfab author",
                }[source]
                yield SourceItem(
                    source="objaverse-xl",
                    source_id=f"{source}:{hashlib.sha1(ident.encode()).hexdigest()[:16]}",
                    path=path,
                    name=title,
                    description=None,
                    tags=[source],
                    category=None,
                    license=licence,
                    attribution=f"{title} by {holder} ({ident})",
                    metadata={
                        "xl_source": source,
                        "source_url": ident,
                        "license_code": row.get("license"),
                        "sha256": row.get("sha256"),
                        **({"rejected": list(verdict)} if verdict else {}),
                    },
                )
