"""The catalog contract: a versioned DuckDB schema, a write API for pipelines and a read API for the simulator.

`catalogs.reader` imports only duckdb and numpy, so `sim` can read a catalog without heavy dependencies.
"""

from catalogs.layout import DEFAULT_CATALOG
from catalogs.schema import SCHEMA_VERSION, CatalogError

__all__ = ["DEFAULT_CATALOG", "SCHEMA_VERSION", "CatalogError"]
