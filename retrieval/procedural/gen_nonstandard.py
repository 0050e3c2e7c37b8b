"""Generators of non-standard infrastructure, part 1: benches, bins, planters, mailboxes, racks, boxes, booths.

Conventions as in gen_standard: x = depth (front +x), y = width, z = height, base at z = 0.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from retrieval.procedural.parts import BLACK, DARK, FOLIAGE, GLASS, METAL, SOIL, WHITE, Ctx, Parts


def bench(g: Ctx, p: Parts) -> str:
    """Slatted seat on two leg frames, with an optional backrest at -x and optional armrests."""
    w, d = g.dim("width"), g.dim("depth")
    back = g.flag("backrest", 0.75) and g.variant.material != "concrete"
    h = g.dim("height", lo=0.75) if back else g.dim("height", hi=0.48)
    sh = min(g.u("seat_height", 0.43, 0.48), h)
    frame = g.body if g.variant.material in ("concrete", "metal") else DARK
    if g.variant.material == "concrete":
        p.slab((-d / 2, d / 2), (-w / 2, w / 2), (sh - 0.1, sh), g.body)
        for y in (-w / 2 + 0.15, w / 2 - 0.15):
            p.slab((-d / 2 + 0.05, d / 2 - 0.05), (y - 0.1, y + 0.1), (0.0, sh - 0.1), g.body)
        return "without backrest"
    x_back = -d / 2 + (0.1 if back else 0.0)
    n = g.pick("slats", [3, 4, 5])
    edges = np.linspace(x_back, d / 2, n + 1)
    for a, b in pairwise(edges):
        p.slab((a + 0.008, b - 0.008), (-w / 2, w / 2), (sh - 0.04, sh), g.body)
    for y in (-w / 2 + 0.12, w / 2 - 0.12):
        p.slab((x_back + 0.02, d / 2 - 0.04), (y - 0.03, y + 0.03), (0.0, sh - 0.04), frame)
        if back:
            p.slab((-d / 2, -d / 2 + 0.05), (y - 0.03, y + 0.03), (sh - 0.04, h - 0.02), frame)
    if back:
        for z in np.linspace(sh + 0.12, h - 0.08, 3):
            p.slab((-d / 2 + 0.02, -d / 2 + 0.06), (-w / 2, w / 2), (z, z + 0.08), g.body)
    arms = back and g.flag("armrests", 0.4)  # armrests would stand above a backless bench's sampled height
    if arms:
        for y in (-w / 2 + 0.12, w / 2 - 0.12):
            p.slab((x_back, d / 2 - 0.06), (y - 0.03, y + 0.03), (sh + 0.2, sh + 0.24), frame)
    return ("with backrest" if back else "without backrest") + (" and armrests" if arms else "")


def trash_bin(g: Ctx, p: Parts) -> str:
    """Round or square bin with a lid and a dark opening."""
    h = g.dim("height")
    shape = g.pick("shape", ["round", "square"])
    d = g.dim("depth")
    w = g.set("width", d) if shape == "round" else g.dim("width", lo=d * 0.8, hi=d * 1.2)
    lid_h = g.u("lid_height", 0.06, 0.12)
    if shape == "round":
        r = d / 2
        p.frustum(r * 0.95, r * 0.98, 0.0, h - lid_h, g.body)
        p.frustum(r, r * 0.9, h - lid_h, h, g.body)
        p.cylinder(r * 0.6, h, h + 0.003, BLACK)
        for z in (0.15, h - lid_h - 0.15):
            p.cylinder(r * 0.99, z, z + 0.03, DARK)
    else:
        p.slab((-d / 2 + 0.01, d / 2 - 0.01), (-w / 2 + 0.01, w / 2 - 0.01), (0.0, h - lid_h), g.body)
        p.slab((-d / 2, d / 2), (-w / 2, w / 2), (h - lid_h, h), g.body)
        p.slab((d / 2 - 0.012, d / 2), (-w * 0.3, w * 0.3), (h - lid_h - 0.18, h - lid_h - 0.03), BLACK)
    return f"with a {shape} body and a lid"


_STREAMS = (("#1e63b5", "paper"), ("#2e8b3e", "glass"), ("#f0c419", "plastic"), ("#9e9e9e", "general waste"))


def recycling_bin(g: Ctx, p: Parts) -> str:
    """Box with two to four compartments, each with a colour-coded lid and a front opening."""
    h, d = g.dim("height"), g.dim("depth")
    n = g.pick("compartments", [2, 3, 4])
    w = g.dim("width", lo=0.3 * n, hi=0.33 * n + 0.05)
    lid = 0.05
    p.slab((-d / 2 + 0.01, d / 2 - 0.01), (-w / 2, w / 2), (0.0, h - lid), g.body)
    edges = np.linspace(-w / 2, w / 2, n + 1)
    for k, (a, b) in enumerate(pairwise(edges)):
        col = _STREAMS[k][0]
        p.slab((-d / 2, d / 2), (a + 0.005, b - 0.005), (h - lid, h), col)
        c = (a + b) / 2
        p.slab((d / 2 - 0.012, d / 2), (c - 0.07, c + 0.07), (h - lid - 0.2, h - lid - 0.08), col)
    return f"with {n} colour-coded compartments for " + ", ".join(s for _, s in _STREAMS[:n])


def planter(g: Ctx, p: Parts) -> str:
    """Square or round pot with soil and a mound of foliage."""
    h = g.dim("height")
    shape = g.pick("shape", ["box", "round"])
    d = g.dim("depth", lo=0.6 if shape == "round" else None)
    w = g.set("width", d) if shape == "round" else g.dim("width", lo=d)
    ph = h * g.u("pot_fraction", 0.45, 0.65)
    if shape == "round":
        p.frustum(d * 0.4, d / 2, 0.0, ph, g.body)
        p.cylinder(d * 0.46, ph - 0.02, ph + 0.005, SOIL)
    else:
        p.slab((-d / 2, d / 2), (-w / 2, w / 2), (0.0, ph), g.body)
        p.slab((-d / 2 + 0.04, d / 2 - 0.04), (-w / 2 + 0.04, w / 2 - 0.04), (ph, ph + 0.005), SOIL)
    n = max(1, round(w / d))
    fh = h - ph
    for y in np.linspace(-w / 2 + w / (2 * n), w / 2 - w / (2 * n), n):
        rx, ry = d * 0.38, min(w / (2 * n), d / 2) * 0.85
        p.sphere((rx, ry, fh * 0.55), (0.0, float(y), h - fh * 0.55), FOLIAGE)
    flowers = g.flag("flowers", 0.5)
    if flowers:
        for k in range(3):
            y = -w / 4 + k * w / 4
            p.sphere(min(d, w) * 0.08, (d * 0.15, y, h - fh * 0.3), "#d81b60", 1)
    return f"with a {'box-shaped' if shape == 'box' else 'round'} pot, shrubs" + (" and flowers" if flowers else "")


def mailbox(g: Ctx, p: Parts) -> str:
    """Red pillar box with a domed cap, or a box on legs with a rounded top; the slot faces +x."""
    if g.variant.color == "red":
        g.set("style", "pillar")
        h, d = g.dim("height", lo=1.35), g.dim("depth", lo=0.45, hi=0.6)
        w = g.set("width", d)
        r = d / 2
        p.cylinder(r, 0.0, 0.1, g.body)
        p.cylinder(r * 0.9, 0.1, h - r * 0.55, g.body)
        p.cylinder(r, h - r * 0.75, h - r * 0.55, g.body)
        p.sphere((r, r, r * 0.55), (0.0, 0.0, h - r * 0.55), g.body)
        zs = h - r * 1.3
        p.slab((r * 0.85, r * 1.0), (-r * 0.4, r * 0.4), (zs, zs + 0.04), BLACK)
        return "of the cylindrical pillar type"
    g.set("style", "box")
    h, d = g.dim("height", hi=1.4), g.dim("depth")
    w = g.dim("width")
    leg = g.u("leg_height", 0.12, 0.22)
    top = h - w / 2
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (leg, top), g.body)
    p.rod((-d / 2, 0.0, top), (d / 2, 0.0, top), w / 2, g.body, sections=24)
    for x in (-d / 2 + 0.04, d / 2 - 0.04):
        for y in (-w / 2 + 0.04, w / 2 - 0.04):
            p.slab((x - 0.03, x + 0.03), (y - 0.03, y + 0.03), (0.0, leg), DARK)
    p.slab((d / 2, d / 2 + 0.01), (-w * 0.3, w * 0.3), (top - 0.05, top + 0.08), DARK)
    return "on legs with a rounded top"


def bike_rack(g: Ctx, p: Parts) -> str:
    """One to four inverted-U hoops in the x-z plane, spaced along y, joined by floor rails when several."""
    h, d = g.dim("height"), g.dim("depth")
    n = g.pick("hoops", [1, 2, 3, 4])
    tube = g.u("tube_radius", 0.024, 0.03)
    spacing = g.u("spacing", 0.75, 0.9)
    w = g.set("width", (n - 1) * spacing + 2 * tube)
    bend = d / 2 - tube
    for y in np.linspace(-w / 2 + tube, w / 2 - tube, n):
        y = float(y)
        for x in (-bend, bend):
            p.rod((x, y, 0.0), (x, y, h - tube - bend), tube, g.body)
        p.arc((0.0, y, h - tube - bend), bend, tube, 0.0, np.pi, g.body, plane="xz")
    if n > 1:
        for x in (-bend, bend):
            p.rod((x, -w / 2 + tube, tube), (x, w / 2 - tube, tube), tube, g.body)
    return f"with {n} inverted-U hoop" + ("s" if n > 1 else "")


def newspaper_box(g: Ctx, p: Parts) -> str:
    """Box on a pedestal with a window and a coin mechanism facing +x."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    ped = g.u("pedestal_height", 0.2, 0.4)
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (0.0, 0.02), DARK)
    p.slab((-0.05, 0.05), (-w * 0.35, w * 0.35), (0.02, ped), DARK)
    p.slab((-d / 2, d / 2 - 0.01), (-w / 2, w / 2), (ped, h - 0.04), g.body)
    p.slab((-d / 2 + 0.02, d / 2 - 0.03), (-w / 2 + 0.02, w / 2 - 0.02), (h - 0.04, h), g.body)
    p.slab((d / 2 - 0.01, d / 2), (-w * 0.38, w * 0.38), (ped + (h - ped) * 0.35, h - 0.12), GLASS)
    p.slab((d / 2 - 0.01, d / 2), (-w * 0.38, w * 0.38), (ped + (h - ped) * 0.22, ped + (h - ped) * 0.28), METAL)
    return "with a window"


def vending_machine(g: Ctx, p: Parts) -> str:
    """Cabinet with a display window, a selection panel and a delivery slot on the +x face."""
    h, d, w = g.dim("height"), g.dim("depth"), g.dim("width")
    f = d / 2 - 0.015
    p.slab((-d / 2, f), (-w / 2, w / 2), (0.0, h), g.body)
    win_w = w * g.u("window_fraction", 0.6, 0.72)
    y0 = -w / 2 + 0.05
    p.slab((f, d / 2), (y0, y0 + win_w), (h * 0.38, h - 0.12), GLASS)
    rows = g.pick("product_rows", [3, 4, 5])
    for k, z in enumerate(np.linspace(h * 0.42, h - 0.2, rows)):
        col = ("#e53935", "#fdd835", "#1e88e5", "#43a047", "#ff7043")[k % 5]
        p.slab((f + 0.001, d / 2 - 0.002), (y0 + 0.03, y0 + win_w - 0.03), (z, z + 0.06), col)
    p.slab((f, d / 2), (y0 + win_w + 0.04, w / 2 - 0.05), (h * 0.45, h * 0.7), DARK)
    p.slab((f, d / 2), (y0, y0 + win_w), (0.15, 0.32), BLACK)
    return f"with {rows} rows of products on display"


def phone_booth(g: Ctx, p: Parts) -> str:
    """Glazed booth with corner posts, glazing bars, a roof (barrel-topped when red) and a sign strip."""
    h, d = g.dim("height"), g.dim("depth")
    w = g.dim("width", lo=d * 0.95, hi=d * 1.05)
    red = g.set("classic", g.variant.color == "red")
    roof = 0.25 if red else 0.12
    wall_top = h - roof
    p.slab((-d / 2 + 0.06, d / 2 - 0.06), (-w / 2 + 0.06, w / 2 - 0.06), (0.1, wall_top), GLASS)
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (0.0, 0.1), g.body)
    for x in (-d / 2, d / 2 - 0.08):
        for y in (-w / 2, w / 2 - 0.08):
            p.slab((x, x + 0.08), (y, y + 0.08), (0.0, wall_top), g.body)
    for z in np.linspace(0.6, wall_top - 0.3, 4):
        p.slab((-d / 2 + 0.05, d / 2 - 0.05), (-w / 2 + 0.05, w / 2 - 0.05), (z, z + 0.03), g.body)
    p.slab((-d / 2, d / 2), (-w / 2, w / 2), (wall_top, h - (roof * 0.5 if red else 0.0)), g.body)
    if red:
        p.sphere((d / 2, w / 2, roof * 0.5), (0.0, 0.0, h - roof * 0.5), g.body)
    p.slab((d / 2 - 0.02, d / 2), (-w * 0.35, w * 0.35), (wall_top - 0.18, wall_top - 0.05), WHITE)
    return "with a domed roof and glazed panels" if red else "with glazed panels"


GENERATORS = {
    "bench": bench,
    "trash_bin": trash_bin,
    "recycling_bin": recycling_bin,
    "planter": planter,
    "mailbox": mailbox,
    "bike_rack": bike_rack,
    "newspaper_box": newspaper_box,
    "vending_machine": vending_machine,
    "phone_booth": phone_booth,
}
