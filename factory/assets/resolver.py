"""Free text -> (category, parameters) with a confidence: "a small blue ceramic bowl".

Lexical and offline: category names and synonyms (longest phrase first, plural forms too),
then fuzzy matching (``rapidfuzz``'s ``fuzz.ratio``) for misspellings and unseen words; size
words ("small", "tall", "king-size"), colours, materials ("rusty metal", "oak") and styles
("mid-century", "cyberpunk", "fairy-tale princess") set dimensions, materials and colours;
condition words ("rusty", "dusty", "golden": :mod:`factory.textures.conditions`) set the
surfaces' weathering and finish. The result says when it had to approximate (fuzzy or fallback
category) and why.

The fuzzy similarity is the normalised Indel similarity ``2 * LCS / (len(a) + len(b))``. It
was ``difflib``'s Ratcliff/Obershelp ratio until issue 13, which is never higher (its matching
blocks are one common subsequence; the LCS is the longest), so a few more misspellings pass the
cutoffs now ("waana": banana, was a box) and ties break differently. Exact phrases decide as
before; of the 200 misspelled or unknown texts of ``scripts/bench_geometry_text.py``, two
resolve to another (equally poor) category and one to another phrase of the same category.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import cache

from rapidfuzz import fuzz, process

from factory.assets.catalog import CATEGORIES
from factory.assets.physics import ALIASES, MATERIALS
from factory.assets.procedural import AssetError, AssetSpec
from factory.textures.conditions import kinds_in

RGBA = tuple[float, float, float, float]

COLORS: dict[str, RGBA] = {
    "red": (0.78, 0.12, 0.12, 1),
    "dark red": (0.45, 0.06, 0.06, 1),
    "burgundy": (0.45, 0.08, 0.15, 1),
    "maroon": (0.4, 0.05, 0.1, 1),
    "pink": (0.95, 0.6, 0.72, 1),
    "rose": (0.9, 0.45, 0.55, 1),
    "orange": (0.95, 0.5, 0.1, 1),
    "yellow": (0.95, 0.85, 0.2, 1),
    "mustard": (0.8, 0.65, 0.15, 1),
    "gold": (0.83, 0.69, 0.22, 1),
    "green": (0.2, 0.6, 0.25, 1),
    "olive": (0.45, 0.48, 0.2, 1),
    "mint": (0.6, 0.88, 0.75, 1),
    "dark green": (0.08, 0.3, 0.12, 1),
    "teal": (0.1, 0.5, 0.5, 1),
    "cyan": (0.1, 0.85, 0.9, 1),
    "turquoise": (0.2, 0.8, 0.75, 1),
    "blue": (0.15, 0.3, 0.8, 1),
    "navy": (0.08, 0.12, 0.35, 1),
    "light blue": (0.6, 0.78, 0.95, 1),
    "sky blue": (0.5, 0.75, 0.95, 1),
    "purple": (0.5, 0.2, 0.65, 1),
    "violet": (0.55, 0.3, 0.85, 1),
    "lavender": (0.75, 0.65, 0.9, 1),
    "magenta": (0.9, 0.1, 0.7, 1),
    "brown": (0.45, 0.28, 0.15, 1),
    "beige": (0.87, 0.8, 0.65, 1),
    "tan": (0.8, 0.68, 0.5, 1),
    "cream": (0.96, 0.93, 0.82, 1),
    "ivory": (0.97, 0.96, 0.88, 1),
    "white": (0.95, 0.95, 0.95, 1),
    "black": (0.07, 0.07, 0.08, 1),
    "grey": (0.5, 0.5, 0.52, 1),
    "gray": (0.5, 0.5, 0.52, 1),
    "dark grey": (0.25, 0.25, 0.27, 1),
    "light grey": (0.78, 0.78, 0.8, 1),
    "silver": (0.77, 0.78, 0.8, 1),
    "charcoal": (0.2, 0.2, 0.22, 1),
}

STYLES: dict[str, tuple[tuple[str, str] | None, tuple[RGBA, RGBA] | None]] = {
    "mid-century": (("walnut", "walnut"), ((0.8, 0.6, 0.2, 1), (0.36, 0.24, 0.15, 1))),
    "cyberpunk": (("metal", "plastic"), ((0.9, 0.1, 0.75, 1), (0.1, 0.9, 0.95, 1))),
    "fairy-tale": (("wood", "fabric"), ((0.97, 0.72, 0.82, 1), (0.98, 0.95, 0.97, 1))),
    "princess": (("wood", "fabric"), ((0.97, 0.72, 0.82, 1), (0.98, 0.95, 0.97, 1))),
    "scandinavian": (("pine", "pine"), ((0.95, 0.95, 0.93, 1), (0.8, 0.66, 0.45, 1))),
    "industrial": (("rusty metal", "concrete"), ((0.35, 0.3, 0.28, 1), (0.2, 0.2, 0.2, 1))),
    "rustic": (("pine", "wood"), ((0.6, 0.45, 0.3, 1), (0.45, 0.32, 0.2, 1))),
    "farmhouse": (("pine", "wood"), ((0.93, 0.92, 0.88, 1), (0.55, 0.4, 0.28, 1))),
    "modern": (None, ((0.92, 0.92, 0.92, 1), (0.1, 0.1, 0.1, 1))),
    "minimalist": (None, ((0.95, 0.95, 0.95, 1), (0.8, 0.8, 0.8, 1))),
    "victorian": (("walnut", "fabric"), ((0.45, 0.08, 0.15, 1), (0.3, 0.18, 0.1, 1))),
    "japanese": (("pine", "paper"), ((0.85, 0.75, 0.55, 1), (0.2, 0.2, 0.2, 1))),
    "boho": (("fabric", "ceramic"), ((0.8, 0.5, 0.35, 1), (0.9, 0.8, 0.6, 1))),
    "art deco": (("brass", "marble"), ((0.1, 0.1, 0.1, 1), (0.83, 0.69, 0.22, 1))),
    "coastal": (("pine", "fabric"), ((0.95, 0.95, 0.93, 1), (0.3, 0.5, 0.75, 1))),
    "gothic": (("walnut", "metal"), ((0.1, 0.08, 0.1, 1), (0.35, 0.05, 0.1, 1))),
    "retro": (("plastic", "metal"), ((0.9, 0.45, 0.2, 1), (0.2, 0.6, 0.6, 1))),
    "futuristic": (("aluminium", "plastic"), ((0.9, 0.92, 0.95, 1), (0.3, 0.7, 0.95, 1))),
}

SIZE_WORDS: dict[str, tuple[float, float, float]] = {
    "tiny": (0.6, 0.6, 0.6),
    "mini": (0.65, 0.65, 0.65),
    "small": (0.78, 0.78, 0.78),
    "little": (0.78, 0.78, 0.78),
    "compact": (0.8, 0.8, 0.85),
    "large": (1.25, 1.25, 1.2),
    "big": (1.25, 1.25, 1.2),
    "huge": (1.6, 1.6, 1.4),
    "giant": (1.8, 1.8, 1.6),
    "oversized": (1.4, 1.4, 1.2),
    "tall": (1.0, 1.0, 1.35),
    "short": (1.0, 1.0, 0.75),
    "low": (1.0, 1.0, 0.75),
    "wide": (1.3, 1.0, 1.0),
    "narrow": (0.75, 1.0, 1.0),
    "long": (1.0, 1.3, 1.0),
    "slim": (0.8, 0.8, 1.0),
}

BED_SIZES: dict[str, tuple[float, float]] = {
    "king": (1.93, 2.03),
    "california king": (1.83, 2.13),
    "queen": (1.52, 2.03),
    "double": (1.37, 1.91),
    "full": (1.37, 1.91),
    "twin": (0.99, 1.91),
    "single": (0.99, 1.91),
}

FUZZY_CUTOFF = 0.72
"""Similarity (``fuzz.ratio / 100``) above which an unknown word is read as the nearest
category name."""
GUESS_CUTOFF = 0.6
"""Below this, a fallback request becomes a plain box (declared as approximated)."""
PREPOSITIONS = (
    r"\s(?:next to|on top of|in front of|on|in|inside|near|beside|with|under|by|for|"
    r"against|facing|behind|above|below|from|to)\s"
)


@dataclass
class Resolution:
    """What the resolver understood.

    Attributes:
        spec: the asset request.
        confidence: 0..1 (1: an exact category name or synonym).
        approximated: the category is a guess (fuzzy match or fallback).
        matched: the phrase that decided the category.
        notes: what was read (size, colour, material, style) and any approximation.
    """

    spec: AssetSpec
    confidence: float
    approximated: bool
    matched: str
    notes: list[str] = field(default_factory=list)


def _vocabulary() -> dict[str, str]:
    vocab: dict[str, str] = {}
    for name, cat in CATEGORIES.items():
        for phrase in (name.replace("_", " "), *cat.synonyms):
            vocab.setdefault(phrase, name)
            vocab.setdefault(_plural(phrase), name)
    return vocab


def _plural(phrase: str) -> str:
    if phrase.endswith(("s", "x", "ch", "sh")):
        return phrase + "es"
    if phrase.endswith("y") and phrase[-2:-1] not in "aeiou":
        return phrase[:-1] + "ies"
    return phrase + "s"


_VOCAB = _vocabulary()
_FUZZY_CHOICES = sorted(_VOCAB, reverse=True)
"""Fuzzy candidates; of equally similar ones the first (alphabetically last) wins."""


@cache
def _phrase_re(phrase: str) -> re.Pattern[str]:
    """The phrase as a whole word (compiled once: ``re``'s own cache holds 512 patterns, fewer
    than the vocabulary, and recompiled them on every call)."""
    return re.compile(rf"(?<![a-z]){re.escape(phrase)}(?![a-z])")


def _find_phrases(text: str, phrases: list[str]) -> list[str]:
    found = []
    for p in sorted(phrases, key=len, reverse=True):
        if p in text and (rx := _phrase_re(p)).search(text):
            found.append(p)
            text = rx.sub(" ", text)
    return found


def resolve(text: str, seed: int = 0, allow_fallback: bool = True) -> Resolution:
    """Reads a free-text object request.

    Args:
        text: e.g. ``"a tall rusty metal stool"``.
        seed: seed of the resulting spec.
        allow_fallback: when nothing matches, return the closest guess (low confidence,
            ``approximated``) instead of raising.

    Raises:
        AssetError: empty text, or nothing recognisable and ``allow_fallback`` is off.
    """
    if not isinstance(text, str) or not text.strip():
        raise AssetError("the asset request is empty: describe an object, e.g. 'a small blue bowl'")
    low = " " + re.sub(r"[^a-z0-9\- ]+", " ", text.lower().replace("_", " ")) + " "
    notes: list[str] = []
    # "a chair next to the table": the object is named before the first preposition
    head = re.split(PREPOSITIONS, low, maxsplit=1)[0] + " "
    cats = _find_phrases(head, list(_VOCAB)) or _find_phrases(low, list(_VOCAB))
    approximated, confidence = False, 1.0
    if cats:
        # the head noun comes last in English noun phrases: prefer the last match
        positions = {c: (head if head.find(c) >= 0 else low).rfind(c) for c in cats}
        matched = max(cats, key=lambda c: (positions[c], len(c)))
        category = _VOCAB[matched]
    else:
        words = [w for w in low.split() if len(w) > 2 and w not in COLORS and w not in SIZE_WORDS]
        best, score = "", 0.0
        for w in reversed(words):
            hit, r, _ = process.extractOne(w, _FUZZY_CHOICES, scorer=fuzz.ratio)
            if r / 100 > score:
                best, score = hit, r / 100
        if score >= FUZZY_CUTOFF:
            matched, category = best, _VOCAB[best]
            approximated, confidence = True, round(score, 2)
            notes.append(
                f"approximated: read {matched!r} for an unknown word (similarity {score:.2f})"
            )
        elif allow_fallback:
            matched, category = best or "cardboard_box", _VOCAB.get(best, "cardboard_box")
            if score < GUESS_CUTOFF:
                category, matched = "cardboard_box", "box"
            approximated, confidence = True, round(min(score, 0.4), 2)
            notes.append(
                f"approximated: no known object in {text!r}; using {category!r} "
                f"(confidence {confidence})"
            )
        else:
            raise AssetError(
                f"could not recognise an object in {text!r}; closest known word: {best!r} "
                f"(similarity {score:.2f}); try one of the categories "
                "(python -m factory.assets --list)"
            )
    cat = CATEGORIES[category]
    dims = list(cat.dims)
    for word in _find_phrases(low, list(SIZE_WORDS)):
        fx, fy, fz = SIZE_WORDS[word]
        dims = [dims[0] * fx, dims[1] * fy, dims[2] * fz]
        notes.append(f"size: {word}")
    if category == "bed":
        for word in _find_phrases(low.replace("-size", "").replace(" size", ""), list(BED_SIZES)):
            dims[0], dims[1] = BED_SIZES[word]
            notes.append(f"bed size: {word}")
            break
    mat_names = list(MATERIALS) + list(ALIASES)
    mats = [ALIASES.get(m, m) for m in _find_phrases(low, mat_names)]
    colors = [COLORS[c] for c in _find_phrases(low, list(COLORS))]
    styles = _find_phrases(low, list(STYLES))
    materials: tuple[str, str] | None = None
    cols: tuple[RGBA, RGBA] | None = None
    for st in styles:
        st_mats, st_cols = STYLES[st]
        materials = materials or st_mats
        cols = cols or st_cols
        notes.append(f"style: {st}")
    if mats:
        materials = (mats[0], mats[1] if len(mats) > 1 else mats[0])
        notes.append(f"material: {', '.join(mats)}")
    if colors:
        cols = (colors[0], colors[1] if len(colors) > 1 else colors[0])
        notes.append(f"colour: {', '.join(_find_phrases(low, list(COLORS)))}")
    if materials and not colors and not styles:
        from factory.assets.physics import material

        cols = (material(materials[0]).rgba, material(materials[1]).rgba)
    spec = AssetSpec(
        category=category,
        dims=tuple(round(float(v), 4) for v in dims),  # type: ignore[arg-type]
        materials=materials,
        colors=cols,
        style=styles[0] if styles else "",
        seed=seed,
        text=text,
        finish=kinds_in(low),
    )
    if spec.finish:
        notes.append(f"condition: {', '.join(spec.finish)}")
    return Resolution(spec, confidence, approximated, matched, notes)
