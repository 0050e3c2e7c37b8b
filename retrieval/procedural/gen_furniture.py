"""Generators of non-standard infrastructure, part 2: shelters, displays, kiosks, cafe furniture, carts, cabinets,
fountains and building facades.

Conventions as in gen_standard: x = depth (front +x), y = width, z = height, base at z = 0.
"""

from __future__ import annotations

import numpy as np

from retrieval.procedural.parts import CONCRETE, DARK, GLASS, METAL, RUBBER, STEEL, WHITE, Ctx, Parts


def bus_shelter(g: Ctx, p: Parts) -> str:
    """Posts, a glazed back wall at -x, a side panel, a roof slab, a bench and an advertising panel."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    roof_t = g.u("roof_thickness", 0.1, 0.2)
    top = h - roof_t
    n_posts = 2 if w < 4.0 else 3
    for y in np.linspace(-w / 2 + 0.1, w / 2 - 0.1, n_posts):
        p.slab((-d / 2 + 0.05, -d / 2 + 0.15), (y - 0.05, y + 0.05), (0.0, top), g.body)
    p.slab((-d / 2 + 0.08, -d / 2 + 0.12), (-w / 2 + 0.15, w / 2 - 0.15), (0.1, top - 0.1), GLASS)
    p.slab((-d / 2 + 0.15, -d / 2 + d * 0.7), (-w / 2 + 0.08, -w / 2 + 0.12), (0.1, top - 0.1), GLASS)
    p.slab((-d / 2 + 0.15, -d / 2 + d * 0.7), (w / 2 - 0.2, w / 2 - 0.08), (0.2, top - 0.2), "#f5f0e1")
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (top, h), g.body)
    p.slab((-d / 2 + 0.15, -d / 2 + 0.55), (-w / 2 + 0.5, w / 2 - 0.6), (0.42, 0.47), METAL)
    roof_sign = g.flag("route_sign", 0.5)
    if roof_sign:
        p.slab((d / 2 - 0.02, d / 2), (w / 2 - 0.8, w / 2 - 0.2), (top - 0.25, top), WHITE)
    return "with a glazed back wall, a bench and an advertising panel"


def advertising_board(g: Ctx, p: Parts) -> str:
    """Framed double-sided poster panel on two legs (or one pedestal) over a base plate."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    legs = g.pick("supports", ["two legs", "pedestal"])
    panel_h = min(h * g.u("panel_fraction", 0.62, 0.75), h - 0.3)
    t = d * 0.55
    p.slab((-d / 2, d / 2), (-w * 0.35, w * 0.35), (0.0, 0.05), DARK)
    if legs == "two legs":
        for y in (-w / 2 + 0.06, w / 2 - 0.06):
            p.slab((-0.04, 0.04), (y - 0.04, y + 0.04), (0.05, h - panel_h), g.body)
    else:
        p.slab((-t / 2, t / 2), (-w * 0.2, w * 0.2), (0.05, h - panel_h), g.body)
    p.slab((-t / 2, t / 2), (-w / 2, w / 2), (h - panel_h, h), g.body)
    for s in (-1, 1):
        x0 = s * t / 2
        p.slab(
            (min(x0, x0 + s * 0.005), max(x0, x0 + s * 0.005)),
            (-w / 2 + 0.06, w / 2 - 0.06),
            (h - panel_h + 0.06, h - 0.06),
            "#f3efe3" if s > 0 else "#e0e7ef",
        )
    return f"on {legs} with a poster on each side"


def kiosk(g: Ctx, p: Parts) -> str:
    """Cabin with an overhanging roof, a serving window and a counter on the +x side."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    over = g.u("roof_overhang", 0.1, 0.3)
    roof_t = g.u("roof_thickness", 0.12, 0.25)
    top = h - roof_t
    bx = (-d / 2 + over, d / 2 - over)
    p.slab(bx, (-w / 2 + over, w / 2 - over), (0.0, top), g.body)
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (top, h), DARK)
    p.slab((bx[1], bx[1] + 0.01), (-w / 2 + over + 0.2, w / 2 - over - 0.2), (1.0, top - 0.35), GLASS)
    p.slab((bx[1], bx[1] + over * 0.8), (-w / 2 + over + 0.1, w / 2 - over - 0.1), (0.95, 1.0), METAL)
    p.slab((bx[1], bx[1] + 0.01), (-w / 2 + over + 0.2, w / 2 - over - 0.2), (top - 0.3, top - 0.05), WHITE)
    awning = g.flag("awning", 0.5)
    if awning:
        p.box((over * 0.9, w - 2 * over, 0.03), (bx[1] + over * 0.45, 0.0, top - 0.32), "#c62828", rot_y=0.35)
    return "with a serving window" + (" and an awning" if awning else "")


def cafe_table(g: Ctx, p: Parts) -> str:
    """Round or square top on a central column and a base."""
    h = g.dim("height")
    shape = g.pick("shape", ["round", "square"])
    d = g.dim("depth")
    w = g.set("width", d) if shape == "round" else g.dim("width", lo=d * 0.9, hi=d * 1.1)
    top_t = g.u("top_thickness", 0.02, 0.04)
    if shape == "round":
        p.cylinder(d / 2, h - top_t, h, g.body, sections=32)
    else:
        p.slab((-d / 2, d / 2), (-w / 2, w / 2), (h - top_t, h), g.body)
    leg = METAL if g.variant.material == "wood" else g.body
    p.cylinder(0.03, 0.03, h - top_t, leg, sections=12)
    p.cylinder(min(d, w) * 0.3, 0.0, 0.03, leg, sections=24)
    return f"with a {shape} top on a pedestal"


def chair(g: Ctx, p: Parts) -> str:
    """Seat on four legs with a backrest at -x; the sitter faces +x."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    sh = g.u("seat_height", 0.43, 0.48)
    leg = g.body if g.variant.material != "wood" else DARK
    lr = 0.012
    for x in (-d / 2 + lr, d / 2 - 0.03):
        for y in (-w / 2 + lr, w / 2 - lr):
            p.rod((x, y, 0.0), (x, y, sh - 0.03), lr, leg, sections=8)
    p.slab((-d / 2 + 0.01, d / 2), (-w / 2, w / 2), (sh - 0.03, sh), g.body)
    for y in (-w / 2 + lr, w / 2 - lr):
        p.rod((-d / 2 + lr, y, sh), (-d / 2 + lr, y, h), lr, leg, sections=8)
    slats = g.pick("back_slats", [1, 2, 3])
    for z in np.linspace(h - 0.08, max(h - 0.08 - 0.09 * (slats - 1), sh + 0.1), slats):
        p.slab((-d / 2, -d / 2 + 0.025), (-w / 2, w / 2), (z, z + 0.08), g.body)
    return f"with a {slats}-slat backrest"


def food_cart(g: Ctx, p: Parts) -> str:
    """Counter body on two wheels with a handle, and an umbrella or a sneeze guard."""
    umbrella = g.flag("umbrella", 0.6)
    h = g.dim("height", lo=1.9) if umbrella else g.dim("height", hi=1.3)
    d, w = g.dim("depth"), g.dim("width")
    wheel_r = g.u("wheel_radius", 0.2, 0.3)
    body_z = (wheel_r * 0.6, wheel_r * 0.6 + g.u("body_height", 0.7, 0.8))
    p.slab((-d / 2 + 0.05, d / 2 - 0.05), (-w / 2, w / 2 - 0.1), body_z, g.body)
    p.slab((-d / 2 + 0.03, d / 2 - 0.03), (-w / 2, w / 2 - 0.1), (body_z[1], body_z[1] + 0.03), STEEL)
    for x in (-d / 2 + 0.03, d / 2 - 0.03):
        yw = -w / 2 + wheel_r + 0.05
        p.rod((x - 0.03, yw, wheel_r), (x + 0.03, yw, wheel_r), wheel_r, RUBBER, sections=20)
    p.rod((0.0, w / 2 - 0.1, body_z[1] - 0.1), (0.0, w / 2, body_z[1] - 0.1), 0.02, METAL)
    for x in (-d / 2 + 0.1, d / 2 - 0.1):
        p.rod((x, w / 2 - 0.1, body_z[1] - 0.1), (x, w / 2, body_z[1] - 0.1), 0.015, METAL)
    p.rod((-d / 2 + 0.1, w / 2, body_z[1] - 0.1), (d / 2 - 0.1, w / 2, body_z[1] - 0.1), 0.02, METAL)
    p.slab((d / 2 - 0.05, d / 2 - 0.04), (-w / 2 + 0.4, w / 2 - 0.3), (body_z[0] + 0.2, body_z[1] - 0.2), WHITE)
    if umbrella:
        pole_top = h - 0.35
        p.cylinder(0.02, body_z[1], pole_top + 0.3, METAL, sections=8)
        canopy = g.pick("canopy_color", ["#c62828", "#1565c0", "#f9a825", "#2e7d32"])
        p.cone(d / 2, pole_top, h, canopy, sections=16)
        return "with an umbrella"
    p.slab((-0.02, 0.02), (-w / 2 + 0.3, w / 2 - 0.2), (body_z[1], h), GLASS)
    return "with a sneeze guard"


def street_cabinet(g: Ctx, p: Parts) -> str:
    """Utility cabinet on a concrete plinth with door seams, a handle and vents on the +x face."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    plinth = g.u("plinth_height", 0.08, 0.2)
    doors = 2 if w > 0.9 else 1
    g.set("doors", doors)
    p.slab((-d / 2 + 0.02, d / 2 - 0.03), (-w / 2 + 0.02, w / 2 - 0.02), (0.0, plinth), CONCRETE)
    p.slab((-d / 2 + 0.02, d / 2 - 0.03), (-w / 2 + 0.02, w / 2 - 0.02), (plinth, h - 0.04), g.body)
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (h - 0.04, h), g.body)
    if doors == 2:
        p.slab((d / 2 - 0.03, d / 2 - 0.025), (-0.005, 0.005), (plinth + 0.05, h - 0.1), DARK)
    for y in [-0.06, 0.06] if doors == 2 else [w / 2 - 0.1]:
        p.slab((d / 2 - 0.03, d / 2 - 0.01), (y - 0.015, y + 0.015), (h * 0.5, h * 0.5 + 0.12), METAL)
    for z in np.linspace(h - 0.3, h - 0.15, 4):
        p.slab((d / 2 - 0.03, d / 2 - 0.025), (-w / 2 + 0.1, -w / 2 + 0.3), (z, z + 0.015), DARK)
    return f"with {doors} door" + ("s" if doors > 1 else "")


def drinking_fountain(g: Ctx, p: Parts) -> str:
    """Pedestal with a basin, a spout and a push button; an optional dog bowl at the +x base."""
    h = g.dim("height")
    bowl = g.flag("dog_bowl", 0.35)
    # The basin is round, so depth follows width; a dog bowl adds 0.2 m in front.
    w = g.dim("width", hi=0.4 if bowl else None)
    d = g.dim("depth", lo=w + 0.2, hi=w + 0.24) if bowl else g.set("depth", w)
    r = w / 2
    xc = -d / 2 + r
    top = h - 0.04
    p.frustum(r * 0.5, r * 0.35, 0.0, top - 0.12, g.body, xy=(xc, 0.0))
    p.frustum(r * 0.45, r, top - 0.15, top, g.body, xy=(xc, 0.0))
    p.cylinder(r * 0.85, top - 0.03, top + 0.002, STEEL, xy=(xc, 0.0))
    p.rod((xc, 0.0, top), (xc + r * 0.3, 0.0, h - 0.012), 0.012, METAL, sections=8)
    p.cylinder(0.02, top - 0.09, top - 0.05, METAL, xy=(xc + r * 0.9, 0.0), sections=8)
    if bowl:
        p.cylinder(0.12, 0.0, 0.08, g.body, xy=(d / 2 - 0.12, 0.0))
    return "with a dog bowl" if bowl else "on a pedestal"


def building_facade(g: Ctx, p: Parts) -> str:
    """Building block whose +x face has storeys of windows, a shop front or door and a cornice."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    storey = g.u("storey_height", 3.0, 3.8)
    floors = g.set("floors", max(2, int(h // storey)))
    storey = h / floors
    bay = g.u("bay_width", 1.6, 2.6)
    bays = g.set("bays", max(2, int(w // bay)))
    bay = w / bays
    f = d / 2 - 0.25
    p.slab((-d / 2, f), (-w / 2, w / 2), (0.0, h - 0.3), g.body)
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (h - 0.3, h), WHITE if g.variant.color != "white" else CONCRETE)
    shop = g.flag("shop_front", 0.6)
    if shop:
        p.slab((f, f + 0.05), (-w / 2 + 0.3, w / 2 - 0.3), (0.3, storey * 0.8), GLASS)
        p.slab((f, f + 0.12), (-w / 2 + 0.2, w / 2 - 0.2), (storey * 0.8, storey * 0.95), DARK)
    else:
        p.slab((f, f + 0.05), (-0.6, 0.6), (0.0, 2.3), "#5d4037")
    for k in range(1, floors):
        z0 = k * storey + storey * 0.25
        for j in range(bays):
            yc = -w / 2 + (j + 0.5) * bay
            p.slab((f, f + 0.06), (yc - bay * 0.28, yc + bay * 0.28), (z0, z0 + storey * 0.5), GLASS)
            p.slab((f, f + 0.12), (yc - bay * 0.32, yc + bay * 0.32), (z0 - 0.08, z0), WHITE)
    return f"with {floors} storeys" + (" and a shop front" if shop else "")


GENERATORS = {
    "bus_shelter": bus_shelter,
    "advertising_board": advertising_board,
    "kiosk": kiosk,
    "cafe_table": cafe_table,
    "chair": chair,
    "food_cart": food_cart,
    "street_cabinet": street_cabinet,
    "drinking_fountain": drinking_fountain,
    "building_facade": building_facade,
}
