"""Style, condition and material words of a request: "a rusty industrial garage".

``STYLE_WORDS`` name a design style (they also choose asset materials and colours, see
:data:`factory.assets.resolver.STYLES`); ``CONDITIONS`` name the state or finish of things
(rusty, dusty, muddy, worn, golden, luxurious, ...), each with its kind of weathering or finish
and the materials it brings; material words ("oak", "velvet", "marble") are those of
:mod:`factory.assets.physics`. :func:`read_style` reads all three; the scene keeps them in the
parsed request so that materials and textures can follow them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache

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


@dataclass(frozen=True)
class Condition:
    """What a condition word means.

    Attributes:
        kind: the weathering or finish: ``rust``, ``dust``, ``dirt``, ``mud``, ``wear``,
            ``scratches``, ``peeling``, ``stains``, ``mould``, ``cracks``, ``faded``, ``clean``,
            ``polished``, ``gold``, ``luxury``.
        materials: materials it brings (names of :data:`factory.assets.physics.MATERIALS`).
    """

    kind: str
    materials: tuple[str, ...] = ()


CONDITIONS: dict[str, Condition] = {
    "rusty": Condition("rust", ("rusty metal",)),
    "rusted": Condition("rust", ("rusty metal",)),
    "rust-covered": Condition("rust", ("rusty metal",)),
    "corroded": Condition("rust", ("rusty metal",)),
    "dusty": Condition("dust"),
    "dust-covered": Condition("dust"),
    "cobwebbed": Condition("dust"),
    "muddy": Condition("mud"),
    "mud-stained": Condition("mud"),
    "dirty": Condition("dirt"),
    "grimy": Condition("dirt"),
    "filthy": Condition("dirt"),
    "messy": Condition("dirt"),
    "stained": Condition("stains"),
    "worn": Condition("wear"),
    "worn-out": Condition("wear"),
    "worn out": Condition("wear"),
    "well-worn": Condition("wear"),
    "weathered": Condition("wear"),
    "shabby": Condition("wear"),
    "run-down": Condition("wear"),
    "rundown": Condition("wear"),
    "dilapidated": Condition("wear"),
    "derelict": Condition("wear"),
    "abandoned": Condition("wear"),
    "battered": Condition("wear"),
    "aged": Condition("wear"),
    "old": Condition("wear"),
    "scratched": Condition("scratches"),
    "scuffed": Condition("scratches"),
    "chipped": Condition("scratches"),
    "peeling": Condition("peeling"),
    "mouldy": Condition("mould"),
    "moldy": Condition("mould"),
    "damp": Condition("mould"),
    "cracked": Condition("cracks"),
    "faded": Condition("faded"),
    "sun-bleached": Condition("faded"),
    "clean": Condition("clean"),
    "spotless": Condition("clean"),
    "pristine": Condition("clean"),
    "brand-new": Condition("clean"),
    "brand new": Condition("clean"),
    "polished": Condition("polished"),
    "shiny": Condition("polished"),
    "glossy": Condition("polished"),
    "lacquered": Condition("polished"),
    "golden": Condition("gold", ("brass",)),
    "gold": Condition("gold", ("brass",)),
    "gilded": Condition("gold", ("brass",)),
    "gold-plated": Condition("gold", ("brass",)),
    "luxurious": Condition("luxury", ("brass", "marble", "fabric")),
    "luxury": Condition("luxury", ("brass", "marble", "fabric")),
    "opulent": Condition("luxury", ("brass", "marble", "fabric")),
    "lavish": Condition("luxury", ("brass", "marble", "fabric")),
    "posh": Condition("luxury", ("brass", "marble", "fabric")),
    "palatial": Condition("luxury", ("brass", "marble", "fabric")),
    "royal": Condition("luxury", ("brass", "marble", "fabric")),
    "regal": Condition("luxury", ("brass", "marble", "fabric")),
    "upscale": Condition("luxury", ("brass", "marble", "fabric")),
    "high-end": Condition("luxury", ("brass", "marble", "fabric")),
    "velvet": Condition("luxury", ("fabric",)),
}
"""Condition word -> its kind and materials."""


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
    """

    style: str = ""
    styles: tuple[str, ...] = ()
    conditions: tuple[str, ...] = ()
    condition_words: tuple[str, ...] = ()
    materials: tuple[str, ...] = ()


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
    return StyleRead(
        style=styles[0] if styles else "",
        styles=styles,
        conditions=tuple(kinds),
        condition_words=tuple(w for _, w in conds),
        materials=tuple(materials),
    )
