"""Style, condition and material words of a request: "a rusty industrial garage".

``STYLE_WORDS`` name a design style (they also choose asset materials and colours, see
:data:`factory.assets.resolver.STYLES`); ``CONDITIONS`` name the state or finish of things
(rusty, dusty, muddy, worn, golden, luxurious, ...), each with its kind of weathering or finish
and the materials it brings (the table is :data:`factory.textures.conditions.CONDITIONS`,
which the asset library and the compiler read too); material words ("oak", "velvet",
"marble") are those of :mod:`factory.assets.physics`. :func:`read_style` reads all three; the
scene keeps them in the parsed request so that materials and textures can follow them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache

from factory.textures.conditions import CONDITIONS, Condition

STYLE_WORDS: tuple[str, ...] = (
    "mid-century",
    "cyberpunk",
    "fairy-tale",
    "princess",
    "scandinavian",
    "industrial",
    "rustic",
    "farmhouse",
    "modern",
    "minimalist",
    "victorian",
    "japanese",
    "boho",
    "art deco",
    "coastal",
    "gothic",
    "retro",
    "futuristic",
)
"""Design styles, in the order :func:`read_style` prefers them for ``style``."""


COLOURS: tuple[str, ...] = (
    "red",
    "blue",
    "green",
    "white",
    "black",
    "yellow",
    "grey",
    "gray",
    "brown",
    "pink",
    "orange",
    "purple",
    "beige",
    "silver",
    "navy",
    "teal",
    "turquoise",
    "cream",
)
"""Colour words (English; :mod:`.foreign_looks` reads them from the other languages)."""

_NOT_WORDS = frozenset({"plant", "organic", "soil"})
"""Material names that are internal to the asset library, not words people use for one."""


@dataclass(frozen=True)
class StyleRead:
    """The style, condition and material words of a request.

    Attributes:
        style: the first design style (``""`` if none): what the agent prefixes to asset texts.
        styles: every design style named, in :data:`STYLE_WORDS` order.
        conditions: the condition kinds named (``rust``, ``dust``, ...), in request order.
        condition_words: the condition words as written.
        materials: material names (canonical, of :data:`~factory.assets.physics.MATERIALS`)
            named directly or brought by a condition, in request order.
        colours: colour words of :data:`COLOURS`, in request order ("gray" read as "grey").
    """

    style: str = ""
    styles: tuple[str, ...] = ()
    conditions: tuple[str, ...] = ()
    condition_words: tuple[str, ...] = ()
    materials: tuple[str, ...] = ()
    colours: tuple[str, ...] = ()


_AGE = re.compile(r"\byears?[\s-]+olds?\b")


@cache
def _word_re(phrase: str) -> re.Pattern[str]:
    return re.compile(rf"(?<![\w-]){re.escape(phrase)}(?![\w-])")


def _find(text: str, phrases: list[str]) -> list[tuple[int, str]]:
    """Whole-word phrases in ``text``, longest first, each span read once; (position, phrase)."""
    found: list[tuple[int, str]] = []
    for p in sorted(phrases, key=len, reverse=True):
        if p not in text:
            continue
        rx = _word_re(p)
        for m in rx.finditer(text):
            found.append((m.start(), p))
        text = rx.sub(lambda m: " " * len(m.group(0)), text)
    return sorted(found)


def read_style(text: str) -> StyleRead:
    """Reads the style, condition and material words of (English) request text.

    Args:
        text: the request, e.g. ``"a dusty victorian library with a golden clock"``.

    Returns:
        what was found; empty fields when nothing was.
    """
    from factory.assets.physics import ALIASES, MATERIALS  # factory.assets is not cheap

    low = _AGE.sub(" ", text.lower().replace("_", " "))  # "a 5 year old's room" is not worn
    styles = tuple(s for s in STYLE_WORDS if s in low)  # "scandinavian-style" too
    conds = _find(low, list(CONDITIONS))
    kinds: list[str] = []
    mats: list[tuple[int, str]] = []
    for pos, word in conds:
        c = CONDITIONS[word]
        if c.kind not in kinds:
            kinds.append(c.kind)
        mats += [(pos, m) for m in c.materials]
    cond_words = {w for _, w in conds}
    names = [m for m in (*MATERIALS, *ALIASES) if m not in cond_words and m not in _NOT_WORDS]
    mats += [(pos, ALIASES.get(m, m)) for pos, m in _find(low, names)]
    materials: list[str] = []
    for _, m in sorted(mats, key=lambda pm: pm[0]):
        if m not in materials:
            materials.append(m)
    colours = tuple(
        dict.fromkeys("grey" if c == "gray" else c for _, c in _find(low, list(COLOURS)))
    )
    return StyleRead(
        style=styles[0] if styles else "",
        colours=colours,
        styles=styles,
        conditions=tuple(kinds),
        condition_words=tuple(w for _, w in conds),
        materials=tuple(materials),
    )


__all__ = ["COLOURS", "CONDITIONS", "STYLE_WORDS", "Condition", "StyleRead", "read_style"]
