"""The scene plot: the one top-down drawing (`sim/topdown.py`) of a spec with every zone, plus axes, scale bar and legend.

The drawing goes onto the plot's Axes as vector collections (`PlotCanvas`), not as a picture: a raster
upsampled to a 1200 dpi figure costs gigabytes, vectors stay sharp and small at any dpi.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from sim.palette import EDGE, OBJECT_CLASS, SURFACE, ZONE, terrain_colour
from sim.scene.scene import Scene, as_scene
from sim.topdown import Colour, dashes, draw_scene

_Item = tuple[np.ndarray, Colour | None, Colour | None, float]  # points, fill (line: colour), outline, width


class PlotCanvas:
    """`sim.topdown.Canvas`'s drawing calls onto a matplotlib Axes; widths in pixels become `pt_per_px` points.

    Consecutive polygons (or lines) become one collection, drawn in call order; a new collection on top
    starts whenever the call kind changes, so the layers stack as they do on a picture.
    """

    def __init__(self, ax: Any, px_per_m: float, pt_per_px: float = 0.4) -> None:
        self.ax, self.px_per_m, self.pt_per_px = ax, px_per_m, pt_per_px
        self._kind, self._z = "", 1.0
        self._items: list[_Item] = []

    def polygon(self, pts: Any, fill: Colour | None, outline: Colour | None = None, width: float = 1.0) -> None:
        """A polygon filled with `fill` (None: not filled), outlined `width` pixels wide when `outline` is given."""
        self._add("polygon", (np.asarray(pts, dtype=np.float64).reshape(-1, 2), fill, outline, width))

    def line(self, pts: Any, colour: Colour, width: float = 1.0, dash: tuple[float, float] | None = None) -> None:
        """A polyline `width` pixels wide; `dash` = (on, off) metres draws it dashed."""
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
        for piece in [pts] if dash is None else dashes(pts, *dash):
            self._add("line", (piece, colour, None, width))

    def disc(self, x: float, y: float, r: float, fill: Colour, outline: Colour | None = None) -> None:
        """A disc of radius `r` metres at (x, y)."""
        a = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
        self.polygon(np.c_[x + r * np.cos(a), y + r * np.sin(a)], fill, outline)

    def finish(self) -> None:
        """Add the last collection to the Axes."""
        from matplotlib.collections import LineCollection, PolyCollection

        if not self._items:
            return
        paths = [i[0] for i in self._items]
        if self._kind == "polygon":
            self.ax.add_collection(
                PolyCollection(
                    paths,
                    facecolors=[_rgba(i[1]) for i in self._items],
                    edgecolors=[_rgba(i[2]) for i in self._items],
                    linewidths=[0.0 if i[2] is None else i[3] * self.pt_per_px for i in self._items],
                    zorder=self._z,
                )
            )
        else:
            self.ax.add_collection(
                LineCollection(
                    paths,
                    colors=[_rgba(i[1]) for i in self._items],
                    linewidths=[i[3] * self.pt_per_px for i in self._items],
                    zorder=self._z,
                )
            )
        self._items, self._z = [], self._z + 0.001

    def _add(self, kind: str, item: _Item) -> None:
        if kind != self._kind:
            self.finish()
            self._kind = kind
        self._items.append(item)


def _rgba(c: Colour | None) -> tuple[float, float, float, float]:
    return (0.0, 0.0, 0.0, 0.0) if c is None else (c[0], c[1], c[2], 1.0)


def render_scene(spec: Scene | Mapping[str, Any], out: str | Path, *, dpi: int = 150, title: str | None = None) -> Path:
    """Draw a scene (a dict is parsed) top-down to a PNG at `out` and return its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch, Rectangle

    scene = as_scene(spec)
    xmin, ymin, xmax, ymax = scene.bounds
    w, h = xmax - xmin, ymax - ymin
    scale = 12.0 / max(w, h)  # inches a metre
    fig, ax = plt.subplots(figsize=(max(w * scale, 4) + 2.5, max(h * scale, 4)))
    ax.set_facecolor(SURFACE["ground"][:3])
    c = PlotCanvas(ax, dpi * scale)
    draw_scene(c, scene, zones=True)
    c.finish()
    bar = 10.0 if max(w, h) < 150 else 50.0
    x0, y0 = xmin + 0.03 * w, ymin + 0.03 * h
    ax.add_patch(Rectangle((x0, y0), bar, max(h, w) * 0.006, color="black"))
    ax.text(x0 + bar / 2, y0 + max(h, w) * 0.015, f"{bar:.0f} m", ha="center", va="bottom", fontsize=8)
    handles = [Patch(color=SURFACE["road"][:3], label="road")] + [
        Patch(color=c, label=k.replace("_", " ")) for k, c in ZONE.items()
    ]
    handles += [
        Patch(facecolor=SURFACE["crosswalk"][:3], edgecolor=EDGE, hatch="||||", label="crosswalk"),
        Patch(color=SURFACE["ramp"][:3], label="curb ramp"),
    ]
    kinds = sorted({(t["kind"], t["surface"]) for t in scene.terrain})  # only the terrain this scene holds
    handles += [Patch(facecolor=terrain_colour(k, s)[:3], edgecolor=EDGE, label=f"{k} ({s})") for k, s in kinds]
    handles += [
        Patch(color=c, label=f"{k.replace('_', '-')} object" if k != "building" else "building facade")
        for k, c in OBJECT_CLASS.items()
    ]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    ax.set_xlim(xmin - 2, xmax + 2)
    ax.set_ylim(ymin - 2, ymax + 2)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    st = scene.stats
    ax.set_title(
        title or f"seed {scene.seed} · blocks {st.get('blocks', '')} · {st.get('objects', 0)} objects", fontsize=9
    )
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out
