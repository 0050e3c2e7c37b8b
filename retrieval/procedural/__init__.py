"""Procedural street-object library: parametric trimesh generators for 33 categories with real-world sizes.

`generate(category, seed)` builds one deterministic variant; `export_asset` writes OBJ+MTL+texture (PyBullet) and
GLB; `to_record` turns it into a catalog row; `contact_sheet` renders a grid of thumbnails. See docs/procedural.md.
"""

from retrieval.procedural.contact import contact_sheet
from retrieval.procedural.export import ExportedAsset, export_asset, pybullet_extents, to_record
from retrieval.procedural.library import GENERATORS, RECIPES, ProceduralAsset, category_names, generate
from retrieval.procedural.spec import CategorySpec, Variant, load_recipes
from retrieval.procedural.views import render_views

__all__ = [
    "RECIPES",
    "GENERATORS",
    "CategorySpec",
    "ExportedAsset",
    "ProceduralAsset",
    "Variant",
    "category_names",
    "contact_sheet",
    "export_asset",
    "generate",
    "load_recipes",
    "pybullet_extents",
    "render_views",
    "to_record",
]
