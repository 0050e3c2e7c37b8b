"""CPU multi-view rendering of an exported procedural asset: the retrieval renderer framed by the known size.

Azimuth is measured in degrees from the +x axis (the asset's front) towards +y; elevation in degrees above the
horizon. One renderer (`retrieval.render.render_obj`, PyBullet TinyRenderer) serves the library's contact
sheets and the retrieval pipeline's views, so both show assets the same way.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np


def render_views(
    obj_path: str | Path, dims: Sequence[float], azimuths: Sequence[float], elevation: float = 20.0, size: int = 224
) -> list[np.ndarray]:
    """Render `obj_path` once per azimuth as RGB uint8 arrays (size x size) on a white background."""
    from retrieval.render import ViewSpec, render_obj

    obj_path = Path(obj_path)
    if not obj_path.is_file():
        raise FileNotFoundError(f"no OBJ at {obj_path}; export the asset first (export_asset)")
    d = np.asarray(dims, dtype=float)
    if d.shape != (3,) or np.any(d <= 0):
        raise ValueError(f"dims must be three positive extents (depth, width, height), got {tuple(dims)}")
    # Library meshes stand on z = 0 centred on x/y, so the size alone gives the bounds to frame.
    bounds = np.array([[-d[0] / 2, -d[1] / 2, 0.0], [d[0] / 2, d[1] / 2, d[2]]])
    specs = [ViewSpec(float(az), float(elevation)) for az in azimuths]
    return render_obj(obj_path, specs, size=size, bounds=bounds)
