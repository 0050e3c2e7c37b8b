"""Road network: block builders (S, C, X, T, O) and MetaDrive-style Block Incremental Generation."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Point, Polygon

from kernel.config import ConfigError
from sim.scene.config import max_sidewalk_width
from sim.scene.geometry import arc, arc_about, largest, straight, strip, unit
from sim.scene.polyline import Polyline

HALF_PI = math.pi / 2


@dataclass
class Roadway:
    """One carriageway: a centerline, its half width, and which sides carry sidewalks and crosswalk candidates."""

    id: str
    centerline: Polyline
    half_width: float
    sides: tuple[int, ...] = (1, -1)  # +1 left, -1 right of the direction of travel
    crosswalk_ends: tuple[str, ...] = ("start", "end")


@dataclass
class Block:
    """A placed block: drivable polygon, roadways, free sockets (point, heading) and its through length."""

    id: str
    code: str
    polygon: Polygon
    roadways: list[Roadway]
    sockets: list[tuple[np.ndarray, float]]
    lanes: int
    lane_width: float
    through_length: float
    island: Polygon | None = None
    parent: int | None = None
    claim: Polygon | None = field(default=None, repr=False)


def _u(rng: np.random.Generator, r: list[float]) -> float:
    return float(rng.uniform(r[0], r[1]))


def _arm(bid: str, k: int, p: np.ndarray, h: float, length: float, hw: float) -> Roadway:
    return Roadway(f"{bid}.{k}", straight(p, h, length), hw)


def build_block(code: str, bid: str, p: np.ndarray, h: float, rng: np.random.Generator, cfg: dict[str, Any]) -> Block:
    """Build block `code` whose entry is the socket (p, h); parameters are drawn from `rng`."""
    lanes = int(rng.integers(cfg["lanes"][0], cfg["lanes"][1] + 1))
    lw = round(_u(rng, cfg["lane_width"]), 2)
    hw = lanes * lw
    ways: list[Roadway] = []
    sockets: list[tuple[np.ndarray, float]] = []
    island = None
    if code == "S":
        cl = straight(p, h, _u(rng, cfg["straight_length"]))
        ways.append(Roadway(f"{bid}.0", cl, hw))
        sockets.append((cl.points[-1], h))
        through = cl.length
    elif code == "C":
        angle = math.radians(_u(rng, cfg["curve_angle"])) * (1 if rng.random() < 0.5 else -1)
        cl = arc(p, h, _u(rng, cfg["curve_radius"]), angle)
        ways.append(Roadway(f"{bid}.0", cl, hw))
        sockets.append((cl.points[-1], h + angle))
        through = cl.length
    elif code in ("X", "T"):
        la = _u(rng, cfg["arm_length"])
        ways.append(_arm(bid, 0, p, h, la, hw))
        centre = p + (la + hw) * unit(h)
        outs = (h, h + HALF_PI, h - HALF_PI) if code == "X" else (h + HALF_PI, h - HALF_PI)
        for k, out_h in enumerate(outs, start=1):
            start = centre + hw * unit(out_h)
            ways.append(_arm(bid, k, start, out_h, la, hw))
            sockets.append((start + la * unit(out_h), out_h))
        if code == "T":
            # The far side of the junction core carries the sidewalk that joins the two arms' far sidewalks.
            a0 = centre + hw * unit(h + HALF_PI)
            ways.append(Roadway(f"{bid}.3", straight(a0, h - HALF_PI, 2 * hw), hw, sides=(1,), crosswalk_ends=()))
        through = 2 * la + 2 * hw
    elif code == "O":
        la = _u(rng, cfg["arm_length"])
        ri = _u(rng, cfg["roundabout_radius"])
        ro = ri + 2 * hw
        r0 = math.sqrt(ro * ro - hw * hw)
        centre = p + (la + ro) * unit(h)
        ways.append(_arm(bid, 0, p, h, la + ro - r0, hw))
        angles = (h + math.pi, h - HALF_PI, h, h + HALF_PI)  # polar angles of the arms, counter-clockwise
        for k, out_h in enumerate(angles[1:], start=1):
            start = centre + r0 * unit(out_h)
            ways.append(_arm(bid, k, start, out_h, la + ro - r0, hw))
            sockets.append((centre + (ro + la) * unit(out_h), out_h))
        for k in range(4):
            # Counter-clockwise ring: its right side faces outward, the left side is the central island.
            ring = arc_about(centre, ri + hw, angles[k], angles[k] + HALF_PI)
            ways.append(Roadway(f"{bid}.{4 + k}", ring, hw, sides=(-1,), crosswalk_ends=()))
        island = Point(centre).buffer(ri, quad_segs=16)
        through = 2 * la + 2 * ro
    else:
        raise ConfigError(f"unknown block code {code!r}")
    parts = [strip(way.centerline, -way.half_width, way.half_width) for way in ways if way.sides != (1,)]
    if code in ("X", "T"):
        centre = p + (ways[0].centerline.length + hw) * unit(h)
        parts.append(
            Polygon([centre + hw * unit(h + quarter * HALF_PI + math.pi / 4) * math.sqrt(2) for quarter in range(4)])
        )
    poly = shapely.union_all(parts)
    if island is not None:
        poly = poly.difference(island)
    # GEOS's mitre join raises the floating-point divide flag on some block outlines (a 20-vertex one of the unseen
    # template, say); the outline it returns is valid and whole, so the flag is not worth a warning in every log.
    with np.errstate(divide="ignore", invalid="ignore"):
        poly = largest(poly.buffer(0.01, join_style="mitre").buffer(-0.01, join_style="mitre")) or poly
    return Block(bid, code, poly, ways, sockets, lanes, lw, through, island)


def _claim(block: Block, margin: float) -> Polygon:
    """The area `block` keeps to itself: its outline (a roundabout's island included) grown by `margin`.

    The island hole is left out: no other block can reach inside a ring road without crossing it, and buffering a
    polygon with a finely curved hole costs ~15x more (GEOS), most of a scene's road-network time.
    """
    poly = block.polygon
    return (Polygon(poly.exterior) if isinstance(poly, Polygon) else poly).buffer(margin, quad_segs=2)


def _overlaps(new: Block, blocks: list[Block], socket: np.ndarray, margin: float) -> bool:
    """Whether `new` comes too close to earlier blocks (its parent only near the joint is allowed)."""
    claim = new.claim = _claim(new, margin)
    for i, other in enumerate(blocks):
        assert other.claim is not None  # set on every placed block: the first by generate_network, the rest here
        if i == new.parent:
            inter = new.polygon.intersection(other.polygon).area
            if inter > 2.0:
                return True
            # Near the shared socket the claims overlap by construction; elsewhere they must not.
            keep_out = Point(socket).buffer(
                2 * margin + 2 * max(other.lanes * other.lane_width, new.lanes * new.lane_width), quad_segs=4
            )
            if claim.difference(keep_out).intersects(other.claim.difference(keep_out)):
                return True
        elif claim.intersects(other.claim):
            return True
    return False


def generate_network(cfg: dict[str, Any], rng: np.random.Generator) -> list[Block]:
    """Grow blocks one by one on free sockets, retrying other shapes and parameters on overlap (BIG)."""
    blocks_cfg = cfg["blocks"]
    explicit = isinstance(blocks_cfg, str)
    num_blocks = len(blocks_cfg) if explicit else int(blocks_cfg)
    margin = max_sidewalk_width(cfg["templates"]) + 0.5
    first = build_block("S" if not explicit else blocks_cfg[0], "r0", np.zeros(2), 0.0, rng, cfg)
    first.claim = _claim(first, margin)
    blocks = [first]
    for i in range(1, num_blocks):
        placed = None
        for attempt in range(cfg["block_tries"]):
            code = blocks_cfg[i] if explicit else cfg["block_types"][int(rng.integers(len(cfg["block_types"])))]
            # Prefer the newest block's sockets (a street that grows onward), then older free ones.
            owners = [j for j in range(len(blocks) - 1, -1, -1) if blocks[j].sockets]
            if not owners:
                break
            j = owners[0] if attempt < cfg["block_tries"] // 2 else owners[int(rng.integers(len(owners)))]
            k = int(rng.integers(len(blocks[j].sockets)))
            sp, sh = blocks[j].sockets[k]
            cand = build_block(code, f"r{i}", sp, sh, rng, cfg)
            cand.parent = j
            if not _overlaps(cand, blocks, sp, margin):
                blocks[j].sockets.pop(k)
                placed = cand
                break
        if placed is None:
            what = f"block {i} ({blocks_cfg[i]})" if explicit else f"block {i}"
            raise ConfigError(
                f"could not place {what} without overlapping the {len(blocks)} earlier blocks after "
                f"{cfg['block_tries']} tries; use fewer blocks, other codes, or raise block_tries"
            )
        blocks.append(placed)
    return blocks


def lane_lines(w: Roadway, lanes: int, lane_width: float) -> list[list[list[float]]]:
    """Painted lines of a roadway: the centre line and the lane dividers, as polylines."""
    if w.sides == (1,):
        return []
    offs = [k * lane_width for k in range(-lanes + 1, lanes)]
    return [np.round(w.centerline.offset(off), 4).tolist() for off in offs]
