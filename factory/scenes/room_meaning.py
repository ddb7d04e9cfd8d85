"""The nearest room type by meaning, for rooms no name or alias of
:data:`~factory.scenes.rooms.ROOM_TYPES` matches ("a barbershop", "a veterinary clinic").

Each room type's *profile* is the set of words of its name, aliases and describing words
(``words`` in the data file). A request's content words (function words, generic place
nouns and words the caller ignores, e.g. object and style words, left out) are compared with
each profile through static GloVe word vectors (:mod:`.word_vectors`); the score is the mean
of two cosines, each in [-1, 1]:

* the weighted mean of the request's word vectors against the profile's mean vector;
* the weighted mean, over the request's words, of the best cosine with a profile word
  (an exact word of the profile scores 1).

Generic place nouns ("shop", "room", "store") weigh :data:`GENERIC_WEIGHT`, the other words 1.
Below :data:`THRESHOLD` no room type is near enough and the caller keeps its default.
Deterministic and offline; the vectors load on first use (about half a second).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

from factory.scenes.word_vectors import word_vectors

log = logging.getLogger(__name__)

THRESHOLD = 0.6
"""The lowest score taken as a match (unrelated words score about 0.2 to 0.55)."""
GENERIC_WEIGHT = 0.25
"""The weight of a generic place noun next to the request's other words."""

STOP_WORDS: frozenset[str] = frozenset(
    [
        "a",
        "an",
        "the",
        "of",
        "in",
        "on",
        "at",
        "for",
        "with",
        "without",
        "and",
        "or",
        "to",
        "from",
        "by",
        "into",
        "onto",
        "over",
        "under",
        "near",
        "my",
        "our",
        "your",
        "his",
        "her",
        "their",
        "its",
        "this",
        "that",
        "these",
        "those",
        "where",
        "which",
        "who",
        "whose",
        "what",
        "there",
        "is",
        "are",
        "be",
        "being",
        "with",
        "some",
        "any",
        "very",
        "much",
        "many",
        "few",
        "lots",
        "full",
        "kind",
        "sort",
        "type",
        "robot",
        "robots",
        "pick",
        "picks",
        "picking",
        "put",
        "puts",
        "place",
        "places",
        "move",
        "moves",
        "grab",
        "grabs",
        "take",
        "takes",
        "up",
        "down",
        "it",
        "them",
        "one",
        "two",
        "three",
        "four",
        "five",
        "six",
        "seven",
        "eight",
        "nine",
        "ten",
        "something",
        "anything",
        "thing",
        "things",
        "scene",
        "scenes",
        "setting",
        "setup",
        "environment",
        "interior",
        "inside",
        "indoor",
        "indoors",
        "nice",
        "good",
        "great",
        "lovely",
        "pretty",
        "beautiful",
        "cute",
        "big",
        "small",
        "large",
        "little",
        "tiny",
        "huge",
        "typical",
        "simple",
        "new",
        "real",
        "realistic",
        "like",
        "looking",
        "style",
        "styled",
        "themed",
    ]
)
"""Words that say nothing about the kind of room."""
GENERIC_WORDS: frozenset[str] = frozenset(
    [
        "room",
        "rooms",
        "shop",
        "shops",
        "store",
        "stores",
        "office",
        "offices",
        "station",
        "studio",
        "hall",
        "house",
        "building",
        "center",
        "centre",
        "space",
        "area",
        "booth",
        "corner",
        "zone",
        "suite",
        "parlor",
        "parlour",
        "quarters",
        "chamber",
    ]
)
"""Place nouns that many room types share: they weigh :data:`GENERIC_WEIGHT`."""


@dataclass(frozen=True)
class RoomGuess:
    """The nearest room type, its score and the request words it was chosen by."""

    room_type: str
    score: float
    words: tuple[str, ...]


def words_of(text: str) -> list[str]:
    """The lower-case words of ``text`` (letters only, two or more)."""
    return [w for w in re.findall(r"[a-z]+", text.lower()) if len(w) > 1]


def content_words(text: str, ignore: Callable[[str], bool] | None = None) -> list[str]:
    """The words of ``text`` that can say what room it is (no stop words, none ignored)."""
    return [w for w in words_of(text) if w not in STOP_WORDS and not (ignore and ignore(w))]


@cache
def _profiles() -> tuple[tuple[str, np.ndarray, np.ndarray], ...] | None:
    """(room type, its words' unit vectors, their unit mean) per room type."""
    from factory.scenes.rooms import ROOM_TYPES

    wv = word_vectors()
    if wv is None:
        return None
    out = []
    for name, rt in ROOM_TYPES.items():
        words = set(words_of(" ".join([name, *rt.aliases, *rt.words])))
        words -= STOP_WORDS | GENERIC_WORDS
        vecs = [v for w in sorted(words) if (v := wv.vector(w)) is not None]
        if not vecs:
            continue
        m = np.array(vecs)
        c = m.mean(axis=0)
        out.append((name, m, c / np.linalg.norm(c)))
    return tuple(out)


def rank_room_types(words: list[str]) -> list[tuple[str, float]]:
    """Every room type with its score for ``words`` (content words), best first; empty
    when no word has a vector or the vectors are not installed."""
    wv = word_vectors()
    profiles = _profiles()
    if wv is None or profiles is None:
        return []
    known = [
        (v, GENERIC_WEIGHT if w in GENERIC_WORDS else 1.0)
        for w in words
        if (v := wv.vector(w)) is not None
    ]
    if not known:
        return []
    q = np.array([v for v, _ in known])
    wts = np.array([wt for _, wt in known])
    wts = wts / wts.sum()
    qc = wts @ q
    qc = qc / (np.linalg.norm(qc) or 1.0)
    scored = [
        (name, 0.5 * float(qc @ c) + 0.5 * float(wts @ (q @ m.T).max(axis=1)))
        for name, m, c in profiles
    ]
    return sorted(scored, key=lambda s: (-s[1], s[0]))


def nearest_room_type(
    text: str, ignore: Callable[[str], bool] | None = None, threshold: float = THRESHOLD
) -> RoomGuess | None:
    """The room type nearest in meaning to the room ``text`` asks for.

    Args:
        text: an English request whose room words match no room type ("a barbershop").
        ignore: words to leave out besides stop words (objects, styles: "a mug").
        threshold: the lowest score taken.

    Returns:
        the guess, or ``None`` when no content word remains, none has a vector, or the best
        score is below ``threshold`` (each case logged).
    """
    words = content_words(text, ignore)
    ranked = rank_room_types(words) if words else []
    if not ranked:
        return None
    best, score = ranked[0]
    if score < threshold:
        log.info(
            "room %r: nearest room type %s scores %.2f < %.2f; default kept",
            text,
            best,
            score,
            threshold,
        )
        return None
    log.info("room %r -> %s (score %.2f)", text, best, score)
    return RoomGuess(best, round(score, 4), tuple(words))
