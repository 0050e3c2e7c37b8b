"""CPU multi-view rendering of a textured OBJ with PyBullet's TinyRenderer (white background, object framed).

Azimuth is measured in degrees from the +x axis (the asset's front) towards +y; elevation in degrees above the
horizon. The camera looks at the centre of the bounding box from a distance at which the bounding sphere fits.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

FOV_DEG = 40.0


def camera_eye(dims: Sequence[float], azimuth: float, elevation: float, fov_deg: float = FOV_DEG) -> np.ndarray:
    """Camera position framing a base-at-z=0, x/y-centred box of extents `dims` from (azimuth, elevation)."""
    d = np.asarray(dims, dtype=float)
    radius = 0.5 * float(np.linalg.norm(d))
    dist = radius / np.sin(np.radians(fov_deg) / 2) * 1.02
    az, el = np.radians(azimuth), np.radians(elevation)
    target = np.array([0.0, 0.0, d[2] / 2])
    return target + dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def render_views(obj_path: str | Path, dims: Sequence[float], azimuths: Sequence[float], elevation: float = 20.0,
                 size: int = 224) -> list[np.ndarray]:
    """Render `obj_path` once per azimuth as RGB uint8 arrays (size x size) on a white background."""
    import pybullet as p

    obj_path = Path(obj_path)
    if not obj_path.is_file():
        raise FileNotFoundError(f"no OBJ at {obj_path}; export the asset first (export_asset)")
    d = np.asarray(dims, dtype=float)
    if d.shape != (3,) or np.any(d <= 0):
        raise ValueError(f"dims must be three positive extents (depth, width, height), got {tuple(dims)}")
    cid = p.connect(p.DIRECT)
    try:
        vis = p.createVisualShape(p.GEOM_MESH, fileName=str(obj_path), physicsClientId=cid)
        if vis < 0:
            raise RuntimeError(f"PyBullet could not load {obj_path} as a visual shape")
        body = p.createMultiBody(0.0, -1, vis, physicsClientId=cid)
        radius = 0.5 * float(np.linalg.norm(d))
        target = [0.0, 0.0, float(d[2]) / 2]
        proj = p.computeProjectionMatrixFOV(FOV_DEG, 1.0, radius * 0.05, radius * 10.0)
        images = []
        for az in azimuths:
            eye = camera_eye(d, float(az), elevation)
            view = p.computeViewMatrix(eye.tolist(), target, [0.0, 0.0, 1.0])
            # Light from over the camera's shoulder so the visible faces are lit.
            light = camera_eye(d, float(az) + 40.0, 55.0) - np.asarray(target)
            _, _, rgba, _, seg = p.getCameraImage(
                size, size, view, proj, renderer=p.ER_TINY_RENDERER, lightDirection=light.tolist(),
                lightAmbientCoeff=0.55, lightDiffuseCoeff=0.5, lightSpecularCoeff=0.05, shadow=0,
                physicsClientId=cid,
            )
            rgb = np.asarray(rgba, dtype=np.uint8).reshape(size, size, 4)[:, :, :3].copy()
            mask = np.asarray(seg).reshape(size, size) != body
            rgb[mask] = 255
            images.append(rgb)
        return images
    finally:
        p.disconnect(cid)
