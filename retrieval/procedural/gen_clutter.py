"""Generators of clutter: cones, barriers, parked bicycles and e-scooters, bags, boxes and cans.

Conventions as in gen_standard: x = depth (front +x; vehicles point +x), y = width, z = height, base at z = 0.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from retrieval.procedural.parts import BLACK, DARK, METAL, RUBBER, STEEL, WHITE, Ctx, Parts


def traffic_cone(g: Ctx, p: Parts) -> str:
    """Square base and a truncated cone with one or two reflective collars."""
    h, d = g.dim("height"), g.dim("depth")
    w = g.set("width", d)
    base_t = 0.03
    r0, r1 = d * 0.36, d * 0.09
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (0.0, base_t), BLACK if g.variant.color == "green" else g.body)
    p.frustum(r0, r1, base_t, h, g.body)
    collars = g.set("collars", 2 if h > 0.6 else 1)
    for k in range(collars):
        za = base_t + (h - base_t) * (0.55 + 0.18 * k)
        zb = za + (h - base_t) * 0.1

        def rad(z: float) -> float:
            return r0 + (r1 - r0) * (z - base_t) / (h - base_t) + 0.003

        p.frustum(rad(za), rad(zb), za, zb, WHITE)
    return f"with {collars} reflective collar" + ("s" if collars > 1 else "")


def barrier(g: Ctx, p: Parts) -> str:
    """Steel crowd-control barrier (rails, pickets, flat feet) or a striped plastic barricade on A-frame legs."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    if g.variant.material == "steel":
        r = 0.02
        top, bottom = h - r, 0.12
        for y in (-w / 2 + r, w / 2 - r):
            p.rod((0.0, y, 0.05), (0.0, y, top), r, g.body)
            p.slab((-d / 2, d / 2), (y - 0.03, y + 0.03), (0.0, 0.05), g.body)
        p.rod((0.0, -w / 2 + r, top), (0.0, w / 2 - r, top), r, g.body)
        p.rod((0.0, -w / 2 + r, bottom), (0.0, w / 2 - r, bottom), r, g.body)
        n = g.set("pickets", int((w - 0.2) / g.u("picket_spacing", 0.1, 0.16)))
        for y in np.linspace(-w / 2 + 0.1, w / 2 - 0.1, n):
            p.rod((0.0, float(y), bottom), (0.0, float(y), top), 0.008, g.body, sections=6)
        return f"of the crowd-control type with {n} pickets"
    for y in (-w / 2 + 0.05, w / 2 - 0.05):
        for s in (-1, 1):
            p.rod((s * (d / 2 - 0.02), y, 0.0), (0.0, y, h - 0.02), 0.02, DARK, sections=8)
    boards = g.pick("boards", [1, 2])
    for k in range(boards):
        z1 = h - 0.05 - k * 0.4
        stripes = int(w / 0.2)
        edges = np.linspace(-w / 2, w / 2, stripes + 1)
        for j, (a, b) in enumerate(pairwise(edges)):
            col = g.body if j % 2 == 0 else WHITE
            p.slab((0.025, 0.045), (a, b), (z1 - 0.2, z1), col)
    return f"of the barricade type with {boards} striped board" + ("s" if boards > 1 else "")


def bicycle(g: Ctx, p: Parts) -> str:
    """Two tyres (tori), a diamond frame of tubes, fork, handlebar along y and saddle; it points +x."""
    L, w, h = g.dim("depth"), g.dim("width"), g.dim("height")
    R = g.u("wheel_radius", min(0.33, (L - 0.95) / 2), min(0.37, (L - 0.95) / 2))
    tyre = 0.022
    xr, xf = -L / 2 + R, L / 2 - R
    axle = R
    bb = (xr + g.u("chainstay", 0.42, 0.46), 0.0, 0.3)
    seat = (bb[0] - 0.12, 0.0, h - 0.08)
    head_top = (xf - 0.2, 0.0, h - 0.12)
    head_bot = (xf - 0.16, 0.0, h - 0.3)
    for x in (xr, xf):
        p.torus(R - tyre, tyre, (x, 0.0, axle), RUBBER)
        p.torus(R - tyre * 2.5, tyre * 0.4, (x, 0.0, axle), STEEL, sections=24)
        p.rod((x, -0.05, axle), (x, 0.05, axle), 0.02, METAL, sections=8)
    tube = 0.018
    for a, b in (
        (bb, seat),
        (seat, head_top),
        (bb, head_bot),
        (head_bot, head_top),
        ((xr, 0.0, axle), bb),
        ((xr, 0.0, axle), (seat[0] + 0.03, 0.0, seat[2] - 0.12)),
        (head_bot, (xf, 0.0, axle)),
    ):
        p.rod(a, b, tube, g.body, sections=8)
    p.rod(head_top, (head_top[0] - 0.05, 0.0, h - 0.02), 0.014, METAL, sections=8)
    p.rod((head_top[0] - 0.05, -w / 2, h - 0.02), (head_top[0] - 0.05, w / 2, h - 0.02), 0.012, DARK)
    p.slab((seat[0] - 0.14, seat[0] + 0.1), (-0.07, 0.07), (seat[2], h - 0.02), BLACK)
    p.rod((bb[0], -0.09, bb[2]), (bb[0], 0.09, bb[2]), 0.012, METAL, sections=8)
    basket = g.flag("basket", 0.3)
    if basket:
        p.slab((xf - 0.2, xf + 0.12), (-0.16, 0.16), (h - 0.3, h - 0.08), METAL)
    return "with a front basket" if basket else "parked on its stand"


def e_scooter(g: Ctx, p: Parts) -> str:
    """Deck on two small wheels, a steering stem at the +x end and a handlebar along y."""
    L, w, h = g.dim("depth"), g.dim("width"), g.dim("height")
    R = g.u("wheel_radius", 0.1, 0.13)
    xr, xf = -L / 2 + R, L / 2 - R
    for x in (xr, xf):
        p.rod((x, -0.025, R), (x, 0.025, R), R, RUBBER, sections=20)
    deck_z = R * 0.7
    p.slab((xr + R * 0.3, xf - R * 0.6), (-0.08, 0.08), (deck_z, deck_z + 0.05), g.body)
    p.rod((xr, 0.0, R), (xr + R * 1.2, 0.0, deck_z + 0.05), 0.015, g.body, sections=8)
    stem_top = (xf - 0.12, 0.0, h - 0.02)
    p.rod((xf, 0.0, R), stem_top, 0.02, g.body)
    p.rod((stem_top[0], -w / 2, h - 0.02), (stem_top[0], w / 2, h - 0.02), 0.016, DARK)
    for s in (-1, 1):
        p.rod((stem_top[0], s * (w / 2 - 0.1), h - 0.02), (stem_top[0], s * w / 2, h - 0.02), 0.02, BLACK)
    p.slab((xf - R * 0.2, xf + 0.03), (-0.03, 0.03), (R * 1.2, R * 1.35), WHITE)
    shared = g.flag("shared_fleet", 0.5)
    return "from a shared fleet" if shared else "parked on its kickstand"


def shopping_bag(g: Ctx, p: Parts) -> str:
    """Bag body with two carrying handles over the top, sometimes with groceries poking out."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    handle_h = g.u("handle_height", 0.08, 0.14)
    body = h - handle_h
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (0.0, body), g.body)
    r = w * 0.2
    for x in (-d / 4, d / 4):
        p.arc((x, 0.0, body + handle_h - r - 0.006), r, 0.006, 0.0, np.pi, g.body, plane="yz", segments=6)
        for s in (-1, 1):
            p.rod((x, s * r, body - 0.02), (x, s * r, body + handle_h - r - 0.006), 0.006, g.body, sections=6)
    groceries = g.flag("groceries", 0.4)
    if groceries:
        p.rod((0.0, -w * 0.2, body * 0.7), (0.0, -w * 0.1, body + handle_h * 0.8), 0.03, "#d9a441")
        p.sphere(min(d, w) * 0.2, (0.0, w * 0.2, body), "#4caf50", 1)
    return "with groceries poking out" if groceries else "with handles"


def cardboard_box(g: Ctx, p: Parts) -> str:
    """Closed carton with packing tape over the top seam and a shipping label on +x."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (0.0, h - 0.002), g.body)
    p.slab((-d / 2 - 0.0005, d / 2 + 0.0005), (-0.025, 0.025), (h - 0.002, h), "#d8c39a")
    label = g.flag("label", 0.6)
    if label:
        p.slab((d / 2, d / 2 + 0.001), (-w * 0.25, w * 0.1), (h * 0.35, h * 0.7), WHITE)
    return "with a shipping label" if label else "taped shut"


def drink_can(g: Ctx, p: Parts) -> str:
    """Can body with tapered shoulders, a silver lid and a printed band."""
    h, d = g.dim("height"), g.dim("depth")
    g.set("width", d)
    r = d / 2
    p.frustum(r * 0.8, r, 0.0, 0.008, STEEL)
    p.cylinder(r, 0.008, h * 0.9, g.body)
    p.frustum(r, r * 0.82, h * 0.9, h - 0.002, STEEL)
    p.cylinder(r * 0.8, h - 0.002, h, STEEL)
    band = WHITE if g.variant.color not in ("silver", "white") else "#c62828"
    p.cylinder(r * 1.003, h * 0.4, h * 0.55, band)
    g.set("volume_ml", int(round(np.pi * (r * 0.98) ** 2 * h * 0.9 * 1e6 / 10) * 10))
    return f"of about {g.params['volume_ml']} ml"


GENERATORS = {
    "traffic_cone": traffic_cone,
    "barrier": barrier,
    "bicycle": bicycle,
    "e_scooter": e_scooter,
    "shopping_bag": shopping_bag,
    "cardboard_box": cardboard_box,
    "drink_can": drink_can,
}
