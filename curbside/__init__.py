"""curbside: urban micromobility research platform (data pipelines, asset catalog, simulator)."""

__version__ = "0.1.0"

# `import curbside` registers the env ids (curbside/PointNav-v0, curbside/SocialNav-v0), as `import sim` does.
import sim as _sim  # noqa: E402, F401
