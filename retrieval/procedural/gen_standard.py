"""Generators of standard infrastructure: lamps, poles, signs, signals, hydrants, bollards, trees, parking meters.

Each generator samples its target extents with `g.dim` (x = depth, y = width, z = height), lays out parts that
fill that box with the front facing +x, and returns the detail phrase of its description.
"""

from __future__ import annotations

import numpy as np
import trimesh

from retrieval.procedural.parts import BARK, BLACK, CONCRETE, DARK, GLASS, LIGHT, METAL, WHITE, Ctx, Parts


def street_lamp(g: Ctx, p: Parts) -> str:
    """Pole on a plinth, an arm reaching +x and a luminaire head at its end."""
    h, reach, w = g.dim("height"), g.dim("depth"), g.dim("width")
    r = g.u("pole_radius", 0.06, min(0.12, w / 3))
    base_h = g.u("base_height", 0.4, 0.9)
    x0 = -reach / 2 + w / 2
    p.cylinder(w / 2, 0.0, base_h, g.body, xy=(x0, 0.0))
    p.frustum(r * 1.2, r * 0.8, base_h, h - 0.05, g.body, xy=(x0, 0.0))
    head_len = g.u("head_length", 0.35, 0.6) if reach > 1.0 else 0.3
    head_h = g.u("head_height", 0.1, 0.18)
    arm_z = h - head_h / 2
    p.rod((x0, 0.0, h - 0.3), (reach / 2 - head_len, 0.0, arm_z), r * 0.6, g.body)
    p.slab((reach / 2 - head_len, reach / 2), (-w * 0.4, w * 0.4), (h - head_h, h), g.body)
    p.slab((reach / 2 - head_len * 0.9, reach / 2 - 0.03), (-w * 0.3, w * 0.3), (h - head_h - 0.02, h - head_h), LIGHT)
    return "with a curved arm"


def utility_pole(g: Ctx, p: Parts) -> str:
    """Tall tapered pole with a crossarm along y carrying insulators."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    p.frustum(d / 2, d * 0.36, 0.0, h - 0.15, g.body, sections=16)
    arm_z = h - g.u("crossarm_drop", 0.35, 0.6)
    p.slab((-0.05, 0.05), (-w / 2, w / 2), (arm_z - 0.05, arm_z + 0.05), "#5a4330")
    n = g.pick("insulators", [2, 3, 4])
    for y in np.linspace(-w / 2 + 0.1, w / 2 - 0.1, n):
        p.cylinder(0.04, arm_z + 0.05, h, "#cfd8dc", xy=(0.0, float(y)), sections=10)
    return f"with a crossarm and {n} insulators"


_SIGN_SHAPES = {
    "red": "octagonal",
    "yellow": "diamond",
    "blue": "square",
    "white": "rectangular",
    "green": "rectangular",
}


def traffic_sign(g: Ctx, p: Parts) -> str:
    """Round post with a sign plate (shape set by the colour) facing +x."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    shape = g.set("shape", _SIGN_SHAPES.get(g.variant.color, "square"))
    plate_t = 0.012
    r = (d - plate_t - 0.004) / 2
    xp = -d / 2 + r
    x_plate = (xp + r, xp + r + plate_t)
    ph = w  # plate height; only rectangles differ (portrait regulatory, landscape guide signs)
    if shape == "rectangular":
        ph = w * (g.u("aspect", 1.1, 1.4) if g.variant.color == "white" else g.u("aspect", 0.5, 0.7))
    p.cylinder(r, 0.0, h - ph * 0.1, METAL, xy=(xp, 0.0), sections=12)
    zc = h - ph / 2
    xc = (x_plate[0] + x_plate[1]) / 2
    if shape == "octagonal":
        rad = w / 2 / np.cos(np.pi / 8)  # flat-to-flat width of the octagon equals w
        plate = p.frustum(rad, rad, -plate_t / 2, plate_t / 2, g.body, sections=8, rot_z=np.pi / 8)
        plate.apply_transform(_to_x_axis(xc, zc))
    elif shape == "diamond":
        s = w / np.sqrt(2)
        p.box((plate_t, s, s), (xc, 0.0, zc), g.body, rot_x=np.pi / 4)
    else:
        p.slab(x_plate, (-w / 2, w / 2), (h - ph, h), g.body)
    legend = BLACK if g.variant.color in ("yellow", "white") else WHITE
    p.slab((x_plate[1], x_plate[1] + 0.003), (-w * 0.3, w * 0.3), (zc - ph * 0.08, zc + ph * 0.08), legend)
    return shape


def _to_x_axis(xc: float, zc: float) -> np.ndarray:
    """Transform turning a z-axis disc into a plate facing +x centred at (xc, 0, zc)."""
    m = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0])
    m[:3, 3] = [xc, 0.0, zc]
    return m


def traffic_light(g: Ctx, p: Parts) -> str:
    """Pole with a three-lamp signal head facing +x."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    r = g.u("pole_radius", 0.05, 0.08)
    xp = -d / 2 + r
    head_h = min(w * g.u("head_aspect", 2.5, 2.9), h * 0.4)
    p.cylinder(r, 0.0, h - head_h * 0.2, g.body, xy=(xp, 0.0), sections=14)
    hx0, hx1 = xp + r, d / 2 - 0.03
    p.slab((hx0, hx1), (-w / 2, w / 2), (h - head_h, h), g.body)
    lamp_r = min(w * 0.32, head_h / 7)
    for k, col in enumerate(("#e53935", "#ffb300", "#43a047")):
        zc = h - head_h * (k + 0.5) / 3
        p.rod((hx1, 0.0, zc), (hx1 + 0.03, 0.0, zc), lamp_r, col, sections=16)
    pedestrian = g.flag("pedestrian_signal", 0.5)
    if pedestrian:
        z = h - head_h - 0.05
        p.slab((hx0, hx1), (-w * 0.45, w * 0.45), (z - w * 0.9, z), BLACK)
    return "with a pedestrian signal" if pedestrian else "with red, amber and green lamps"


_BONNETS = {"blue": "#1e88e5", "green": "#43a047", "orange": "#fb8c00", "red": "#e53935"}


def fire_hydrant(g: Ctx, p: Parts) -> str:
    """Barrel on a flange with a bonnet, two side outlets along y and a pumper outlet facing +x."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    rb = min(d, w) * g.u("barrel_fraction", 0.28, 0.34)
    rf = rb * 1.3
    xc = -d / 2 + rf
    body_h = h * 0.72
    p.cylinder(rf, 0.0, 0.06, g.body, xy=(xc, 0.0))
    p.cylinder(rb, 0.06, body_h, g.body, xy=(xc, 0.0))
    p.cylinder(rf * 0.95, body_h, body_h + 0.05, g.body, xy=(xc, 0.0))
    # NFPA 291 bonnet colours encode the rated flow class.
    bonnet_name = g.pick("bonnet_color", list(_BONNETS))
    bonnet = _BONNETS[bonnet_name]
    p.frustum(rb, rb * 0.45, body_h + 0.05, h - 0.05, bonnet, xy=(xc, 0.0))
    p.cylinder(0.025, h - 0.05, h, bonnet, xy=(xc, 0.0), sections=5)
    zn = body_h * 0.72
    p.rod((xc, 0.0, zn), (xc, w / 2, zn), rb * 0.35, g.body)
    p.rod((xc, 0.0, zn), (xc, -w / 2, zn), rb * 0.35, g.body)
    p.rod((xc, 0.0, zn * 0.85), (d / 2, 0.0, zn * 0.85), rb * 0.5, g.body)
    return f"with a {bonnet_name} bonnet"


def bollard(g: Ctx, p: Parts) -> str:
    """Round post with a domed or flat cap and a reflective band."""
    h = g.dim("height")
    d = g.dim("depth", hi=0.3 if g.variant.material == "concrete" else 0.2)
    g.set("width", d)
    r = d / 2
    cap = g.pick("cap", ["dome", "flat"])
    top = h - (r * 0.6 if cap == "dome" else 0.0)
    p.cylinder(r, 0.0, top, g.body)
    if cap == "dome":
        p.sphere((r, r, r * 0.6), (0.0, 0.0, top), g.body)
    band = WHITE if g.variant.color != "yellow" else BLACK
    p.cylinder(r * 1.02, top - 0.12, top - 0.07, band)
    return f"with a {cap} top and a reflective band"


def tree(g: Ctx, p: Parts) -> str:
    """Trunk cylinder and a crown: an ellipsoid with smaller lumps, or a cone for a conifer."""
    h = g.dim("height")
    w = g.dim("width", lo=0.3 * h, hi=0.75 * h)
    d = g.dim("depth", lo=0.85 * w, hi=1.15 * w)
    conifer = g.set("conifer", g.variant.color == "dark green")
    trunk_r = g.u("trunk_radius", 0.08, 0.08 + 0.02 * h)
    crown_z = h * g.u("crown_base", 0.3, 0.45)
    p.frustum(trunk_r * 1.3, trunk_r * 0.8, 0.0, crown_z + (h - crown_z) * 0.3, BARK, sections=12)
    if conifer:
        cone = p.cone(1.0, crown_z, h, g.body, sections=16)
        cone.vertices[:, 0] *= d / 2
        cone.vertices[:, 1] *= w / 2
        return "conifer"
    c = (h - crown_z) / 2
    p.sphere((d / 2, w / 2, c), (0.0, 0.0, crown_z + c), g.body)
    # Lumps poke out of the ellipsoid so the crown reads as foliage, but stay inside the sampled box.
    rr = 0.42 * min(d / 2, w / 2, c)
    a0 = g.u("lump_angle", 0.0, 2 * np.pi)
    for k in range(5):
        a, up = a0 + 2 * np.pi * k / 5, (0.35 if k % 2 else -0.1)
        x, y = (d / 2 - rr) * 0.95 * np.cos(a), (w / 2 - rr) * 0.95 * np.sin(a)
        p.sphere(rr, (x, y, crown_z + c * (1 + up)), g.body, 1)
    return "deciduous"


def parking_meter(g: Ctx, p: Parts) -> str:
    """Post with a rounded meter head whose display faces +x."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    head_h = g.u("head_height", 0.35, 0.5)
    top_r = min(w / 2, head_h * 0.3)
    p.cylinder(0.045, 0.0, h - head_h, METAL, sections=12)
    p.slab((-d / 2, d / 2 - 0.01), (-w / 2, w / 2), (h - head_h, h - top_r), g.body)
    p.rod((-d / 2, 0.0, h - top_r), (d / 2 - 0.01, 0.0, h - top_r), top_r, g.body, sections=16)
    zc = h - head_h * 0.45
    p.slab((d / 2 - 0.01, d / 2), (-w * 0.3, w * 0.3), (zc, zc + head_h * 0.25), GLASS)
    p.slab((d / 2 - 0.01, d / 2), (-w * 0.08, w * 0.08), (zc - 0.08, zc - 0.05), DARK)
    p.slab((-d / 2 + 0.02, d / 2 - 0.03), (-0.08, 0.08), (0.0, 0.02), CONCRETE)
    return "with a digital display"


GENERATORS = {
    "street_lamp": street_lamp,
    "utility_pole": utility_pole,
    "traffic_sign": traffic_sign,
    "traffic_light": traffic_light,
    "fire_hydrant": fire_hydrant,
    "bollard": bollard,
    "tree": tree,
    "parking_meter": parking_meter,
}
