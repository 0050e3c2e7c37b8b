"""Versioned DuckDB schema of the asset catalog (tables: meta, assets, views, descriptions, matches, embeddings, rejections).

Conventions every writer follows (docs/catalog.md):
- meshes are in metres, +z up, base at z = 0, centred on the x/y origin; the front faces +x;
- `depth` is the extent along x, `width` along y, `height` along z;
- file paths are stored relative to the directory that holds the catalog file.
"""

from __future__ import annotations

SCHEMA_VERSION = 1
DEFAULT_TEXT_MODEL = "all-MiniLM-L6-v2"  # the packaged text encoder: catalogs embed with it unless told otherwise
# What a model argument or a catalog's embedding_model may say to mean the packaged model.
DEFAULT_TEXT_MODEL_NAMES = (None, "", DEFAULT_TEXT_MODEL, f"sentence-transformers/{DEFAULT_TEXT_MODEL}")
DEFAULT_EMBEDDING_DIM = 384  # DEFAULT_TEXT_MODEL's width

OBJECT_CLASSES = ("standard", "non_standard", "clutter")

# `embeddings.owner_kind` values: text search ranks ASSET_TEXT vectors, so every writer of assets uses it.
ASSET_TEXT_KIND = "asset_text"
ASSET_IMAGE_KIND = "asset_image"
ASSET_VIEW_KIND = "asset_view"  # one per scored view, model "<scorer>#view<NN>": what attribute queries rank by
DESCRIPTION_KIND = "description"
# The embeddings that belong to one asset: deleted with it.
ASSET_KINDS = (ASSET_TEXT_KIND, ASSET_IMAGE_KIND, ASSET_VIEW_KIND)
ZONES = ("near_road_buffer", "furnishing", "clear", "frontage_buffer", "frontage", "building")


class CatalogError(RuntimeError):
    """A catalog that is missing, of another schema version, or otherwise unusable."""


class CatalogMissing(CatalogError):
    """No catalog file at the path (or the path is a directory): build one there or fix the path."""


class CatalogLocked(CatalogError):
    """Another process holds the catalog's DuckDB write lock; the file is fine, wait and retry (never rebuild)."""


class CatalogCorrupt(CatalogError):
    """The file is damaged (checksum mismatch) or not a DuckDB database at all: rebuild it or restore a copy."""


class CatalogSchemaError(CatalogError):
    """A readable DuckDB file that is not a curbside catalog of this schema version: rebuild or upgrade."""


def stored_version(meta: dict[str, str]) -> int:
    """The schema version recorded in a catalog's meta table; -1 when absent or unreadable."""
    try:
        return int(meta.get("schema_version", -1))
    except (TypeError, ValueError):
        return -1


def ddl(embedding_dim: int = DEFAULT_EMBEDDING_DIM) -> list[str]:
    """Return the CREATE statements of the schema; text embeddings are FLOAT[embedding_dim] arrays."""
    return [
        "CREATE TABLE IF NOT EXISTS meta (key VARCHAR PRIMARY KEY, value VARCHAR NOT NULL)",
        """CREATE TABLE IF NOT EXISTS assets (
            asset_id VARCHAR PRIMARY KEY,
            source VARCHAR NOT NULL,
            source_id VARCHAR NOT NULL,
            category VARCHAR NOT NULL,
            object_class VARCHAR NOT NULL,
            zones VARCHAR[] NOT NULL,
            depth DOUBLE NOT NULL,
            width DOUBLE NOT NULL,
            height DOUBLE NOT NULL,
            mass DOUBLE,
            up_axis VARCHAR NOT NULL DEFAULT '+z',
            front_axis VARCHAR NOT NULL DEFAULT '+x',
            color VARCHAR,
            material VARCHAR,
            description VARCHAR NOT NULL,
            synonyms VARCHAR[] NOT NULL,
            license VARCHAR NOT NULL,
            attribution VARCHAR,
            mesh_path VARCHAR,
            glb_path VARCHAR,
            collision VARCHAR NOT NULL DEFAULT 'box',
            collision_path VARCHAR,
            face_count INTEGER,
            watertight BOOLEAN,
            content_hash VARCHAR,
            params JSON
        )""",
        """CREATE TABLE IF NOT EXISTS views (
            asset_id VARCHAR NOT NULL,
            view_index INTEGER NOT NULL,
            azimuth DOUBLE NOT NULL,
            elevation DOUBLE NOT NULL,
            image_path VARCHAR NOT NULL,
            informative BOOLEAN NOT NULL DEFAULT FALSE,
            informativeness DOUBLE,
            PRIMARY KEY (asset_id, view_index)
        )""",
        """CREATE TABLE IF NOT EXISTS descriptions (
            description_id VARCHAR PRIMARY KEY,
            text VARCHAR NOT NULL,
            category VARCHAR,
            cluster_id INTEGER,
            members VARCHAR[],
            sources VARCHAR[],
            country_counts JSON
        )""",
        """CREATE TABLE IF NOT EXISTS matches (
            asset_id VARCHAR NOT NULL,
            description_id VARCHAR NOT NULL,
            score DOUBLE NOT NULL,
            image_score DOUBLE,
            text_score DOUBLE,
            scorer VARCHAR NOT NULL,
            rank INTEGER,
            PRIMARY KEY (asset_id, description_id)
        )""",
        f"""CREATE TABLE IF NOT EXISTS embeddings (
            owner_kind VARCHAR NOT NULL,
            owner_id VARCHAR NOT NULL,
            model VARCHAR NOT NULL,
            vector FLOAT[{int(embedding_dim)}] NOT NULL,
            PRIMARY KEY (owner_kind, owner_id, model)
        )""",
        """CREATE TABLE IF NOT EXISTS rejections (
            source VARCHAR NOT NULL,
            source_id VARCHAR NOT NULL,
            stage VARCHAR NOT NULL,
            reason VARCHAR NOT NULL,
            detail VARCHAR,
            config_hash VARCHAR,
            PRIMARY KEY (source, source_id, stage)
        )""",
    ]


# Columns of `assets` in insertion order; the writer binds rows by these names.
ASSET_COLUMNS = (
    "asset_id",
    "source",
    "source_id",
    "category",
    "object_class",
    "zones",
    "depth",
    "width",
    "height",
    "mass",
    "up_axis",
    "front_axis",
    "color",
    "material",
    "description",
    "synonyms",
    "license",
    "attribution",
    "mesh_path",
    "glb_path",
    "collision",
    "collision_path",
    "face_count",
    "watertight",
    "content_hash",
    "params",
)
