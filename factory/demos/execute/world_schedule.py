"""Which episode each world of a GPU call runs at each recorded frame.

A GPU call steps all of its worlds together, one recording period (``1 / fps``) after another;
after each period every world's frame is drawn and filed. Episodes differ in length (a scene's
pick-and-place episodes run 140-340 frames), so a call that gives each world one episode runs
until its longest one ends while the others hold still: a third of the work is padding.

A :class:`WorldSchedule` says, for every frame boundary ``b`` of a call and every world ``w``,
which episode the world records (``episode[b, w]``, -1 for none), which of the episode's frames
that is (``frame[b, w]``), whether the world starts that episode at ``b`` (``start[b, w]``: the
world is reset to the episode's initial state right after the period that ends at ``b``), and
the row of the call's flat frame buffers the frame is filed in (``row[b, w]``, -1 for none).

- :func:`padded_schedule`: one episode per world, all starting together (the call runs to the
  longest; frames past an episode's end are not filed). Rows are frame-major
  (``row = b * n + w``), so an episode's frames are a strided view of the buffers.
- :func:`packed_schedule`: more episodes than worlds; a world starts its next episode as soon as
  its last one has recorded its final frame, longest episodes first (LPT), so the call's length
  is about ``sum(frames) / worlds``. Rows are episode-major (an episode's frames are one
  contiguous block).

The schedule is computed on the host before the call (episode lengths are known once planned)
and uploaded as small ``(B, n)`` tables the capture graph indexes by a device-side step counter.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class WorldSchedule:
    """Episodes of a GPU call laid out over its worlds and frame boundaries.

    Attributes:
        episode: (B, n) int32, the episode world ``w`` records at boundary ``b`` (-1: none).
            Between boundaries ``b`` and ``b + 1`` a world steps the episode of boundary ``b``.
        frame: (B, n) int32, that episode's frame index (0 at its start).
        start: (B, n) bool, the world begins ``episode[b, w]`` at ``b`` (``b > 0``: it is reset
            to the episode's initial state after the period ending at ``b``).
        row: (B, n) int32, row of the call's flat frame buffers for that frame (-1: not filed).
        n_rows: rows of the flat frame buffers.
        rows: per episode, the ``slice`` of rows holding its frames in order.
        n_frames: per episode, its number of frames.
    """

    episode: np.ndarray
    frame: np.ndarray
    start: np.ndarray
    row: np.ndarray
    n_rows: int
    rows: list[slice]
    n_frames: list[int]

    @property
    def boundaries(self) -> int:
        """B: frame boundaries of the call (frame 0 included); it runs ``B - 1`` periods."""
        return int(self.episode.shape[0])

    @property
    def worlds(self) -> int:
        """n: worlds of the call."""
        return int(self.episode.shape[1])

    @property
    def resets(self) -> bool:
        """Whether any world starts an episode after the first boundary."""
        return bool(self.start[1:].any())

    def busy(self) -> float:
        """Share of world-frames that record an episode frame (1 - padding)."""
        return float((self.row >= 0).sum()) / max(1, self.row.size)


def padded_schedule(n_frames: list[int]) -> WorldSchedule:
    """One episode per world, all starting at boundary 0 (world ``i`` runs episode ``i``).

    Args:
        n_frames: frames of each episode (>= 1).

    Returns:
        a schedule of ``max(n_frames)`` boundaries; rows frame-major (``b * n + w``).
    """
    n = len(n_frames)
    frames = np.asarray(n_frames, np.int64)
    if n == 0 or frames.min() < 1:
        raise ValueError(f"episodes need at least one frame each: {n_frames}")
    nb = int(frames.max())
    b = np.arange(nb)[:, None]
    w = np.arange(n)[None, :]
    live = b < frames[None, :]
    episode = np.broadcast_to(w, (nb, n)).astype(np.int32)
    frame = np.broadcast_to(b, (nb, n)).astype(np.int32)
    start = np.zeros((nb, n), bool)
    start[0] = True
    row = np.where(live, b * n + w, -1).astype(np.int32)
    rows = [slice(i, i + n * (int(f) - 1) + 1, n) for i, f in enumerate(frames)]
    return WorldSchedule(episode, frame, start, row, nb * n, rows, [int(f) for f in frames])


def packed_schedule(n_frames: list[int], worlds: int) -> WorldSchedule:
    """Episodes packed onto ``worlds`` worlds back to back, longest first.

    Each world takes the next-longest episode as soon as it is free (the one that frees earliest
    first; ties by world index), so the call lasts about ``sum(n_frames) / worlds`` boundaries
    and its end is ragged by at most the length of the last (shortest) episodes. Deterministic.

    Args:
        n_frames: frames of each episode (>= 1).
        worlds: worlds of the call (at most ``len(n_frames)`` are used).

    Returns:
        the schedule; rows episode-major in the order of ``n_frames``.
    """
    e = len(n_frames)
    frames = np.asarray(n_frames, np.int64)
    if e == 0 or frames.min() < 1:
        raise ValueError(f"episodes need at least one frame each: {n_frames}")
    n = max(1, min(int(worlds), e))
    offsets = np.concatenate([[0], np.cumsum(frames)])
    order = sorted(range(e), key=lambda i: (-int(frames[i]), i))
    free = [(0, w) for w in range(n)]  # (first free boundary, world)
    heapq.heapify(free)
    placed: list[tuple[int, int, int]] = []  # (episode, world, start boundary)
    for i in order:
        t, w = heapq.heappop(free)
        placed.append((i, w, t))
        heapq.heappush(free, (t + int(frames[i]), w))
    nb = max(t for t, _ in free)
    episode = np.full((nb, n), -1, np.int32)
    frame = np.zeros((nb, n), np.int32)
    start = np.zeros((nb, n), bool)
    row = np.full((nb, n), -1, np.int32)
    for i, w, t in placed:
        f = int(frames[i])
        episode[t : t + f, w] = i
        frame[t : t + f, w] = np.arange(f)
        start[t, w] = True
        row[t : t + f, w] = offsets[i] + np.arange(f)
    rows = [slice(int(offsets[i]), int(offsets[i + 1])) for i in range(e)]
    return WorldSchedule(
        episode, frame, start, row, int(offsets[-1]), rows, [int(f) for f in frames]
    )


def worlds_for(n_frames: list[int], most: int) -> int:
    """Worlds to pack episodes of these lengths onto: as many as keep the call about as long as
    its longest episode (``sum / max``), at most ``most``. More worlds would only idle while the
    longest episode runs; fewer would lengthen the call."""
    if not n_frames:
        return 1
    return max(1, min(int(most), -(-sum(n_frames) // max(n_frames))))
