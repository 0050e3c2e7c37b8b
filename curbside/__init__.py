"""curbside: urban micromobility research platform (data pipelines, asset catalog, simulator)."""

__version__ = "0.1.0"
