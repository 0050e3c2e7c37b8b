"""Descriptions of procedural assets with the attributes they assert, and which assets satisfy which description.

Every caption carries its requirements, e.g. "a grey trash bin" requires category trash_bin and colour gray. An
asset satisfies a caption when it meets every requirement; training treats all satisfying assets in a batch as
positives (not only the asset the caption was drawn for), so "a photo of a bench" is never pushed away from
another bench. Colours come with families ("dark green" is also "green") and spellings ("grey").
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

# A colour also answers to its family's names: a dark green lamp is a green lamp, a light gray cabinet a gray one.
COLOUR_FAMILY = {
    "dark green": ("green",),
    "light green": ("green",),
    "light gray": ("gray",),
    "tan": ("brown",),
    "terracotta": ("orange", "brown"),
    "beige": ("tan",),
}
SPELLINGS = {"gray": ("gray", "grey"), "light gray": ("light gray", "light grey")}
SIZE_WORDS = {"small": ("small", "short", "low"), "large": ("tall", "large", "big")}

Requirement = tuple[tuple[str, str], ...]


@dataclass(frozen=True)
class Attributes:
    """What a description may assert about one asset."""

    category: str
    colours: frozenset[str]  # its colour and the colour's family
    material: str
    size: str  # "small", "medium" or "large" within its category's height range
    details: frozenset[str]  # "with a lid", "with 2 doors", ... (phrases of its description)
    names: tuple[str, ...]  # the category's display name first, then its synonyms
    description: str


def size_class(height: float, lo: float, hi: float) -> str:
    """Thirds of the category's height range: small, medium, large."""
    t = (height - lo) / (hi - lo) if hi > lo else 0.5
    return "small" if t < 1 / 3 else "large" if t > 2 / 3 else "medium"


def detail_phrases(description: str) -> frozenset[str]:
    """The "with ..." phrases of a generated description, each on its own ("with a round body and a lid" gives
    "with a round body" and "with a lid")."""
    out = set()
    for m in re.finditer(r"\bwith (.+)$", description):
        for part in re.split(r",? and |, ", m.group(1)):
            words = part.strip()
            if words and not re.search(r"\d", words):  # counts ("3 insulators") are not visible attributes
                out.add(f"with {words}")
    return frozenset(out)


def attributes_of(asset) -> Attributes:  # noqa: ANN001 - retrieval.procedural.ProceduralAsset
    """The attributes a procedural asset shows: category, colour (+ family), material, size third, details."""
    from retrieval.procedural.library import RECIPES

    lo, hi = RECIPES[asset.category].height
    colours = frozenset((asset.color, *COLOUR_FAMILY.get(asset.color, ())))
    return Attributes(
        asset.category,
        colours,
        asset.material,
        size_class(asset.dims[2], lo, hi),
        detail_phrases(asset.description),
        (asset.category.replace("_", " "), *asset.synonyms),
        asset.description,
    )


def satisfies(attrs: Attributes, requirement: Requirement) -> bool:
    """Whether an asset with `attrs` meets every (key, value) of a caption's requirement."""
    for key, value in requirement:
        ok = (
            attrs.category == value
            if key == "category"
            else value in attrs.colours
            if key == "colour"
            else attrs.material == value
            if key == "material"
            else attrs.size == value
            if key == "size"
            else value in attrs.details
            if key == "detail"
            else attrs.description == value
        )
        if not ok:
            return False
    return True


def _spell(colour: str, rng: np.random.Generator) -> str:
    names = SPELLINGS.get(colour, (colour,))
    return names[int(rng.integers(len(names)))]


def caption(attrs: Attributes, rng: np.random.Generator) -> tuple[str, Requirement]:
    """One random description of an asset with `attrs` and what it requires."""
    cat = ("category", attrs.category)
    name = attrs.names[0] if rng.random() < 0.6 else attrs.names[int(rng.integers(len(attrs.names)))]
    colour = sorted(attrs.colours)[int(rng.integers(len(attrs.colours)))]
    col = _spell(colour, rng)
    kind = int(rng.integers(10))
    if kind == 0:
        return f"a photo of a {attrs.names[0]}", (cat,)
    if kind == 1:
        return f"a {name}", (cat,)
    if kind in (2, 3):
        prefix = "a photo of a " if rng.random() < 0.3 else "a "
        return f"{prefix}{col} {name}", (cat, ("colour", colour))
    if kind == 4:
        return f"a {attrs.material} {name}", (cat, ("material", attrs.material))
    if kind == 5:
        return f"a {col} {attrs.material} {name}", (cat, ("colour", colour), ("material", attrs.material))
    if kind == 6 and attrs.size != "medium":
        words = SIZE_WORDS[attrs.size]
        return f"a {words[int(rng.integers(len(words)))]} {name}", (cat, ("size", attrs.size))
    if kind == 7 and attrs.details:
        detail = sorted(attrs.details)[int(rng.integers(len(attrs.details)))]
        return f"a {name} {detail}", (cat, ("detail", detail))
    if kind == 8:
        return f"a {col} object", (("colour", colour),)
    return attrs.description, (cat, ("colour", colour), ("material", attrs.material))


def positives(attrs: list[Attributes], requirements: list[Requirement]) -> np.ndarray:
    """(len(attrs), len(requirements)) bool matrix: asset i satisfies caption j."""
    return np.array([[satisfies(a, r) for r in requirements] for a in attrs], dtype=bool).reshape(
        len(attrs), len(requirements)
    )
