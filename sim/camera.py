"""The ego camera: RGB, metric depth and per-pixel semantic classes from one PyBullet render (docs/cameras.md).

TinyRenderer (CPU) by default; the EGL plugin (`renderer: egl`) draws through the GPU's OpenGL when one is
present. Both go through `EgoCamera.capture`, so observations are the same arrays either way.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from catalogs.categories import NAMES
from kernel.config import ConfigError
from kernel.quiet import pybullet as p

# The camera's config declarations live in the light sim.tasks.sensors (the task config and `curbside --help`
# read them without pybullet); imported here so sim.camera names them too.
from sim.tasks.sensors import (  # noqa: F401
    CAMERA_DEFAULTS,
    CAMERA_KEYS,
    CAMERA_TABLE,
    MODALITIES,
    check_clipping_planes,
)

# Semantic ids: surfaces, then the 33 object categories (catalogs/categories.csv order), then what moves.
SURFACES = ("unlabeled", "ground", "road", "crosswalk", "sidewalk", "ramp", "building")
SEMANTIC_CLASSES: tuple[str, ...] = (*SURFACES, *NAMES, "agent", "vehicle", "ego")
SEMANTIC_ID = {name: k for k, name in enumerate(SEMANTIC_CLASSES)}


_EGL: dict[int, int] = {}  # client -> loaded plugin id


def load_egl(client: int) -> None:
    """Load PyBullet's EGL renderer plugin into `client`; a clear ConfigError where no GPU or EGL is present."""
    if client in _EGL:
        return
    import importlib.abc
    import pkgutil

    if not any(os.path.exists(f"/dev/nvidia{k}") for k in range(8)) and not os.path.exists("/dev/dri/renderD128"):
        raise ConfigError(
            "camera.renderer 'egl' needs a GPU with EGL (no /dev/nvidia* or /dev/dri/renderD128 here); "
            "use renderer 'tiny' (CPU) or run on a GPU machine"
        )
    egl = pkgutil.get_loader("eglRenderer")
    # The plugin is an extension module: its loader (an ExecutionLoader) knows the file; no loader, no plugin.
    if isinstance(egl, importlib.abc.ExecutionLoader):
        plugin = p.loadPlugin(egl.get_filename("eglRenderer"), "_eglRendererPlugin", physicsClientId=client)
    else:
        plugin = -1
    if plugin < 0:
        raise ConfigError(
            "PyBullet's EGL plugin failed to load (eglRenderer); check the GPU driver's libEGL, or "
            "use camera.renderer 'tiny'"
        )
    _EGL[client] = plugin


def camera_spaces(cfg: Mapping[str, Any]) -> dict[str, Any]:
    """Gymnasium spaces of a camera config's modalities: rgb (H, W, 3) uint8, depth (H, W, 1) m, semantic (H, W)."""
    import gymnasium as gym

    h, w, far = int(cfg["height"]), int(cfg["width"]), float(cfg["far"])
    table = {
        "rgb": gym.spaces.Box(0, 255, (h, w, 3), np.uint8),
        "depth": gym.spaces.Box(0.0, far, (h, w, 1), np.float32),
        "semantic": gym.spaces.Box(0, len(SEMANTIC_CLASSES) - 1, (h, w), np.uint8),
    }
    return {m: table[m] for m in cfg["modalities"]}


def forget_egl(client: int) -> None:
    """Forget that `client` has the EGL plugin (call on disconnect: PyBullet reuses client ids)."""
    _EGL.pop(client, None)


def linear_depth(buffer: np.ndarray, near: float, far: float) -> np.ndarray:
    """Metric depth along the optical axis (m) from an OpenGL depth buffer in [0, 1], at most `far`."""
    b = np.asarray(buffer, dtype=np.float64)
    return np.minimum(far * near / (far - (far - near) * b), far).astype(np.float32)


class EgoCamera:
    """A camera on the front of the ego machine; `capture()` returns the configured modalities as arrays."""

    def __init__(self, client: int, world: Any, cfg: Mapping[str, Any]) -> None:
        self.client, self.world = client, world
        self.modalities = tuple(cfg["modalities"])
        self.width, self.height = int(cfg["width"]), int(cfg["height"])
        self.fov, self.near, self.far = float(cfg["fov"]), float(cfg["near"]), float(cfg["far"])
        self.mount_height = cfg["mount_height"]
        self.pitch = math.radians(float(cfg["pitch"]))
        self.renderer = p.ER_TINY_RENDERER
        if cfg["renderer"] == "egl":
            load_egl(client)
            self.renderer = p.ER_BULLET_HARDWARE_OPENGL
        self.projection = p.computeProjectionMatrixFOV(self.fov, self.width / self.height, self.near, self.far)
        self._lut = np.zeros(0, dtype=np.uint8)
        self._lut_key: tuple[Any, ...] = ()

    @property
    def intrinsics(self) -> np.ndarray:
        """The 3x3 pinhole matrix K of the images (pixels; principal point at the centre)."""
        f = 0.5 * self.height / math.tan(math.radians(self.fov) / 2)
        return np.array([[f, 0.0, self.width / 2], [0.0, f, self.height / 2], [0.0, 0.0, 1.0]])

    def view(self, machine: Any) -> list[float]:
        """The view matrix at the machine's front, `mount_height` up, looking ahead and `pitch` down."""
        x, y, z = machine.position
        s, yaw = machine.spec, machine.yaw
        c, sn = math.cos(yaw), math.sin(yaw)
        up = float(self.mount_height if self.mount_height is not None else s.height)
        eye = [x + 0.5 * s.length * c, y + 0.5 * s.length * sn, z + up]
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        target = [eye[0] + c * cp, eye[1] + sn * cp, eye[2] + sp]
        return p.computeViewMatrix(eye, target, [-c * sp, -sn * sp, cp])

    def capture(self, machine: Any, extra_kinds: Mapping[int, str] | None = None) -> dict[str, np.ndarray]:
        """One render from the machine's camera: {modality: array} for the configured modalities."""
        semantic = "semantic" in self.modalities
        flags = 0 if semantic else p.ER_NO_SEGMENTATION_MASK
        _, _, rgba, depth, seg = p.getCameraImage(
            self.width,
            self.height,
            self.view(machine),
            self.projection,
            renderer=self.renderer,
            flags=flags,
            shadow=0,
            physicsClientId=self.client,
        )
        h, w = self.height, self.width
        out: dict[str, np.ndarray] = {}
        if "rgb" in self.modalities:
            out["rgb"] = np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3].copy()
        if "depth" in self.modalities:
            out["depth"] = linear_depth(np.reshape(depth, (h, w, 1)), self.near, self.far)
        if semantic:
            out["semantic"] = self.classes(np.reshape(seg, (h, w)), machine.body, extra_kinds or {})
        return out

    def classes(self, seg: np.ndarray, ego: int, extra_kinds: Mapping[int, str]) -> np.ndarray:
        """Semantic ids of a segmentation mask of body ids (-1: nothing drawn there)."""
        n = p.getNumBodies(physicsClientId=self.client)
        # By content: SocialNav removes and adds bodies, and Bullet hands a freed id to the next new body.
        key = (n, ego, frozenset(extra_kinds.items()))
        if self._lut_key != key:
            self._lut = self._table(n, ego, extra_kinds)
            self._lut_key = key
        body = np.asarray(seg, dtype=np.int64) & ((1 << 24) - 1)  # the link index rides in the high bits
        body = np.where(np.asarray(seg) < 0, len(self._lut) - 1, np.minimum(body, len(self._lut) - 1))
        return self._lut[body]

    def _table(self, n: int, ego: int, extra_kinds: Mapping[int, str]) -> np.ndarray:
        """Body id -> semantic id, for ids up to the client's largest (last entry: background)."""
        top = max([n, ego + 1, *(b + 1 for b in extra_kinds)]) + 1
        lut = np.zeros(top + 1, dtype=np.uint8)
        world = self.world
        for body, kind in world.kinds.items():
            name = world.object_category(body) if kind == "object" else kind
            lut[body] = SEMANTIC_ID.get(name, 0)
        for body, kind in extra_kinds.items():
            lut[body] = SEMANTIC_ID.get(kind, 0)
        lut[ego] = SEMANTIC_ID["ego"]
        return lut
