"""The category vocabulary shared by the pipelines, the asset library and the scene generator."""

from __future__ import annotations

# Exact names: the scene generator and the asset library key their tables on these strings.
GROUPS: dict[str, tuple[str, ...]] = {
    "standard": (
        "street_lamp", "utility_pole", "traffic_sign", "traffic_light", "fire_hydrant", "bollard", "tree",
        "parking_meter",
    ),
    "non_standard": (
        "bench", "trash_bin", "recycling_bin", "planter", "mailbox", "bike_rack", "newspaper_box",
        "vending_machine", "phone_booth", "bus_shelter", "advertising_board", "kiosk", "cafe_table", "chair",
        "food_cart", "building_facade", "street_cabinet", "drinking_fountain",
    ),
    "clutter": ("traffic_cone", "barrier", "bicycle", "e_scooter", "shopping_bag", "cardboard_box", "drink_can"),
}

CATEGORIES: tuple[str, ...] = tuple(c for cats in GROUPS.values() for c in cats)
_GROUP_OF = {c: g for g, cats in GROUPS.items() for c in cats}


def category_group(category: str) -> str:
    """Group (standard, non_standard, clutter) of a vocabulary category; raises on unknown names."""
    try:
        return _GROUP_OF[category]
    except KeyError:
        raise ValueError(f"unknown category {category!r}; valid: {', '.join(CATEGORIES)}") from None


def check_category(category: str, *, where: str) -> str:
    """Return `category` if it is in the vocabulary, else raise naming `where` it came from."""
    if category not in _GROUP_OF:
        raise ValueError(
            f"{where}: category {category!r} is not in the curbside vocabulary; use one of: {', '.join(CATEGORIES)}"
        )
    return category


def category_words(category: str) -> str:
    """Human words for a category name ('trash_bin' -> 'trash bin')."""
    return category.replace("_", " ")
