"""Reads a Spanish, French, German or Chinese request as English, word by word, and says which
words it could not read.

The language is the one with the most words of its own in the request
(:data:`~.foreign_words.FOREIGN_WORDS`, words that are English as well not counted); English wins
ties. A foreign request is read through its language's words, the longest phrase first ("salle de
bain" before "salle"); its words that no table knows are *unknown* and reported. An English request
keeps its text unless it holds foreign words that are not English words too ("a bedroom with a
taza"); Chinese words are read in any request, and Chinese characters no table knows are unknown.
The English reading of "recoge la taza y ponla en el cuenco" is "pick up the mug and put it in the
bowl": the request parser reads it as any other.
"""

from __future__ import annotations

import logging
import re
import unicodedata
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

from factory.scenes.foreign_words import (
    ENGLISH_WORDS,
    FALSE_FRIENDS,
    FOREIGN_WORDS,
    LANGUAGE_NAMES,
)

log = logging.getLogger(__name__)

_CJK = r"\u3000-\u303f\u3400-\u4dbf\u4e00-\u9fff\uf900-\ufaff\uff00-\uffef"
_CJK_RUN = re.compile(rf"[{_CJK}]+")
_TOKEN = re.compile(
    r"(?<![^\W\d_])(?:qu|[ldjmnst])'(?=[^\W\d_])"  # French elision: l'évier, d'enfant
    r"|[^\W\d_]+(?:[-'][^\W\d_]+)*'?"
    r"|\d+"
)
_MAX_PHRASE = 4
"""Longest phrase of the tables, in words."""


@dataclass(frozen=True)
class Translation:
    """A request read as English.

    Attributes:
        text: the English reading (the request itself when nothing was translated).
        language: ``"en"``, ``"es"``, ``"fr"``, ``"de"`` or ``"zh"`` (the language most of its
            words are in).
        words: (foreign word or phrase, English) for every one translated, in order.
        unknown: the words no table knows, in order (none are reported in English text but
            for accented or Chinese words).
    """

    text: str
    language: str = "en"
    words: tuple[tuple[str, str], ...] = ()
    unknown: tuple[str, ...] = ()

    @property
    def warning(self) -> str:
        """A sentence naming the words not understood (``""`` if none)."""
        if not self.unknown:
            return ""
        lang = LANGUAGE_NAMES.get(self.language, self.language)
        return (
            f"words not understood in this {lang} request: "
            + ", ".join(repr(w) for w in self.unknown)
            + " (kept untranslated; rooms, homes and common objects are read in English, "
            "Spanish, French, German and Chinese)"
        )


def _tokens(text: str) -> list[tuple[int, int, str]]:
    return [(m.start(), m.end(), m.group(0)) for m in _TOKEN.finditer(text)]


@cache
def _table(lang: str) -> dict[tuple[str, ...], str]:
    """The language's words, keyed by their tokens."""
    return {tuple(t for _, _, t in _tokens(k)): v for k, v in FOREIGN_WORDS[lang].items()}


@cache
def _borrowed() -> dict[tuple[str, ...], str]:
    """Foreign content words that may stand in an English request (not English words)."""
    out: dict[tuple[str, ...], str] = {}
    for lang in ("es", "fr", "de"):
        for key, en in _table(lang).items():
            word = key[0]
            if len(key) == 1 and (
                word in FALSE_FRIENDS
                or word in ENGLISH_WORDS
                or en == word
                or (len(word) < 4 and word.isascii())
            ):
                continue
            out.setdefault(key, en)
    return out


def _language(tokens: list[str], chinese: int, known: Callable[[str], bool]) -> str:
    """The language with the most words of its own; ``chinese``: Chinese words read."""
    english = sum(t in ENGLISH_WORDS or known(t) for t in tokens)
    best, score = ("zh", chinese) if chinese > english else ("en", english)
    for lang in ("es", "fr", "de"):
        table = _table(lang)
        own = sum((t,) in table and table[(t,)] != t and t not in ENGLISH_WORDS for t in tokens)
        if own > score:
            best, score = lang, own
    return best


def _read_latin(
    low: str, lang: str, known: Callable[[str], bool]
) -> tuple[list[tuple[int, int, str]], list[str]]:
    """(start, end, English) spans to replace and the unknown words of Latin-script text."""
    toks = _tokens(low)
    words = [t for _, _, t in toks]
    table = _table(lang) if lang != "en" else {}
    borrowed = _borrowed()
    spans: list[tuple[int, int, str]] = []
    unknown: list[str] = []
    i = 0
    while i < len(toks):
        for n in range(min(_MAX_PHRASE, len(toks) - i), 0, -1):
            key = tuple(words[i : i + n])
            en = table.get(key)
            if en is None:
                en = borrowed.get(key)
            if en is not None:
                spans.append((toks[i][0], toks[i + n - 1][1], en))
                i += n
                break
        else:
            word = words[i]
            foreign = lang != "en" or not word.isascii()
            if foreign and not word.isdigit() and word not in ENGLISH_WORDS and not known(word):
                unknown.append(word)
            i += 1
    return spans, unknown


def _read_chinese(run: str, offset: int) -> tuple[list[tuple[int, int, str]], list[str]]:
    """Greedy longest-match reading of a run of Chinese characters."""
    table = FOREIGN_WORDS["zh"]
    longest = max(len(k) for k in table)
    spans: list[tuple[int, int, str]] = []
    unknown: list[str] = []
    pending = ""
    i = 0
    while i < len(run):
        for n in range(min(longest, len(run) - i), 0, -1):
            en = table.get(run[i : i + n])
            if en is not None:
                if pending:
                    unknown.append(pending)
                    pending = ""
                spans.append((offset + i, offset + i + n, en))
                i += n
                break
        else:
            if not unicodedata.category(run[i]).startswith(("P", "Z")):
                pending += run[i]
            i += 1
    if pending:
        unknown.append(pending)
    return spans, unknown


def _rebuild(low: str, spans: list[tuple[int, int, str]]) -> str:
    out: list[str] = []
    pos = 0
    for start, end, en in sorted(spans):
        out += [low[pos:start], f" {en} " if en else " "]
        pos = end
    out.append(low[pos:])
    text = re.sub(r"[ \t]+", " ", "".join(out))
    return re.sub(r" ([,.;:!?])", r"\1", text).strip()


def _never(word: str) -> bool:
    return False


def translate(text: str, known: Callable[[str], bool] = _never) -> Translation:
    """Reads ``text`` as English.

    Args:
        text: the request, in any of the languages of :data:`~.foreign_words.FOREIGN_WORDS`.
        known: English words the caller understands although no table lists them (object and
            style names), so that a foreign request's English words are not reported.

    Returns:
        the English reading, the language, the words translated and those not understood.
    """
    low = unicodedata.normalize("NFC", text).lower().replace("\u2019", "'").replace("\u2018", "'")
    spans: list[tuple[int, int, str]] = []
    unknown: list[str] = []
    for m in _CJK_RUN.finditer(low):
        s, u = _read_chinese(m.group(0), m.start())
        spans += s
        unknown += u
    latin = _CJK_RUN.sub(lambda m: " " * len(m.group(0)), low)
    lang = _language([t for _, _, t in _tokens(latin)], len(spans) + len(unknown), known)
    s, u = _read_latin(latin, "en" if lang == "zh" else lang, known)
    spans += s
    unknown += u
    if not spans and not unknown:
        return Translation(text)
    words = tuple((low[a:b], en) for a, b, en in sorted(spans) if low[a:b] != en)
    english = _rebuild(low, spans) if spans else text
    result = Translation(english, lang, words, tuple(dict.fromkeys(unknown)))
    if result.words:
        log.info("read the %s request %r as %r", LANGUAGE_NAMES[lang], text, english)
    return result
