"""Condition words: the state or finish of things ("rusty", "dusty", "worn", "golden").

Each word has a kind of weathering or finish and the materials it brings. The table lives
here, below the asset library and the compiler, because both read it: the asset resolver and
:func:`kinds_in` turn the words of an object's text or a floor's material ("dusty oak") into
weathering layers (:mod:`.weathering`) and finishes (:func:`.looks.styled_look`);
:mod:`factory.scenes.style_words` reads them in requests.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache


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


@cache
def condition_pattern() -> re.Pattern[str]:
    """A regular expression matching any condition word (whole words, longest first)."""
    words = sorted(CONDITIONS, key=len, reverse=True)
    return re.compile(r"(?<![\w-])(" + "|".join(re.escape(w) for w in words) + r")(?![\w-])")


def kinds_in(text: str) -> tuple[str, ...]:
    """The condition kinds named in ``text`` (English, any case), in the order they occur,
    each once: ``"a dusty, rusty old shelf"`` -> ``("dust", "rust", "wear")``."""
    kinds: list[str] = []
    low = text.lower().replace("_", " ")
    low = re.sub(r"\byears?[\s-]+olds?\b", " ", low)  # "a 5 year old's room" is not worn
    for m in condition_pattern().finditer(low):
        kind = CONDITIONS[m.group(1)].kind
        if kind not in kinds:
            kinds.append(kind)
    return tuple(kinds)
