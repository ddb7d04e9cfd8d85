"""What the evaluation envs share: episode book-keeping, observation buffers, step outcomes
and renderers.

:class:`EpisodeEnv` is the common base of :class:`~factory.policy.vector_env.PickPlaceVecEnv`
(the fixed-base Panda) and :class:`~factory.policy.mobile_env.MobileVecEnv` (the Panda on the
Omron base): both keep one episode record per env (:class:`Episode`), the latest
observations in one buffer per key with a leading batch axis, a renderer for the observed
cameras and one for videos (:class:`Renderer`); the simulation, the controller and the success
check stay with each env.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, Protocol, TypeVar

import numpy as np


@dataclass
class Episode:
    """Book-keeping of one env's running episode (each env adds its own to it).

    Attributes:
        seed: the seed it was reset from (None for a state or qpos reset).
        limit: frames before it is truncated; steps: frames stepped so far.
        done: whether it has ended; success: whether it ended in success.
        reason: the failure reason (empty on success or while running).
        details: the success check's numbers.
        start_z, max_z: the pick object's height (m) at the start and its highest so far.
        history: the last frames' states, for the check that the object is at rest.
    """

    seed: int | None = None
    limit: int = 0
    steps: int = 0
    done: bool = False
    success: bool = False
    reason: str = ""
    details: dict[str, float] = field(default_factory=dict)
    start_z: float = 0.0
    max_z: float = 0.0
    history: deque[np.ndarray] = field(default_factory=deque)


class _CameraConfig(Protocol):
    @property
    def cameras(self) -> tuple[str, ...]: ...


class Renderer(Protocol):
    """A renderer of some cameras of a scene (the demos' frame renderers)."""

    @property
    def cfg(self) -> _CameraConfig: ...

    def close(self) -> None: ...


E = TypeVar("E", bound=Episode)
R = TypeVar("R", bound=Renderer)


class EpisodeEnv(Generic[E, R]):
    """The book-keeping of ``num_envs`` episodes stepped together.

    Subclasses set ``num_envs``, ``_episodes``, ``_obs`` (:meth:`_empty_obs`), ``renderer`` and
    ``_video`` in their ``__init__`` and give :meth:`_video_renderer` a renderer factory.
    """

    num_envs: int
    _episodes: list[E]
    _obs: dict[str, np.ndarray]
    renderer: R | None
    _video: R | None

    # ---- set-up helpers
    def _empty_obs(self, shapes: dict[str, tuple[tuple[int, ...], str]]) -> dict[str, np.ndarray]:
        """Zeroed observation buffers (n, ...) for one env's key -> (shape, dtype)."""
        return {k: np.zeros((self.num_envs, *shape), dtype) for k, (shape, dtype) in shapes.items()}

    def _reset_ids(self, ids: list[int] | None, *starts: Any) -> list[int]:
        """The envs a reset starts (default all), checking that exactly one of its ways to
        start (seeds, states or qpos) is given.

        Raises:
            ValueError: none or more than one of ``starts`` is given.
        """
        ids = list(range(self.num_envs)) if ids is None else list(ids)
        if sum(x is not None for x in starts) != 1:
            raise ValueError("reset needs exactly one of seeds, states or qpos")
        return ids

    def _episode_start(
        self, k: int, seeds: list[int] | None, max_steps: list[int] | None, default: int
    ) -> tuple[int | None, int]:
        """``seed`` and step limit of the ``k``-th episode a reset starts (``default``: the
        env's limit, unless ``max_steps`` gives one per episode)."""
        seed = None if seeds is None else int(seeds[k])
        return seed, default if max_steps is None else int(max_steps[k])

    # ---- episodes
    def observations(self) -> dict[str, np.ndarray]:
        """The latest observation of every env (copies), (n, ...) per key."""
        return {k: v.copy() for k, v in self._obs.items()}

    def _reset_info(self) -> dict[str, Any]:
        """The info a reset returns: ``{"seed": [...]}`` of every env."""
        return {"seed": [e.seed for e in self._episodes]}

    def _step_outcome(
        self, was_done: np.ndarray, terminal: tuple[str, ...] = ()
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Rewards, terminated, truncated and info of a step, from the episodes' records.

        Args:
            was_done: (n,) which envs had ended before the step.
            terminal: failure reasons that terminate an episode even at its step limit.

        Returns:
            rewards (n,) (1 on the step of success), terminated (n,), truncated (n,) (the step
            limit) and info with ``success``, ``reason`` and ``steps`` (n,) each.
        """
        eps = self._episodes
        success = np.array([e.success for e in eps])
        new = self.done & ~was_done
        truncated = new & np.array([e.steps >= e.limit and not e.success for e in eps])
        if terminal:
            truncated &= np.array([e.reason not in terminal for e in eps])
        terminated = new & ~truncated
        info = {
            "success": success,
            "reason": np.array([e.reason for e in eps], dtype=object),
            "steps": self.steps,
        }
        return (new & success).astype(np.float32), terminated, truncated, info

    @property
    def steps(self) -> np.ndarray:
        """(n,) int: frames stepped in each env's episode."""
        return np.array([e.steps for e in self._episodes])

    @property
    def done(self) -> np.ndarray:
        """(n,) bool: which envs' episodes have ended."""
        return np.array([e.done for e in self._episodes])

    def _result(self, i: int) -> dict[str, Any]:
        """Env ``i``'s episode so far: success, reason, steps, seed and the check's numbers."""
        e = self._episodes[i]
        return {
            "success": e.success,
            "reason": e.reason,
            "steps": e.steps,
            "seed": e.seed,
            "details": dict(e.details),
        }

    # ---- rendering
    def _video_renderer(self, cameras: tuple[str, ...], make: Callable[[], R]) -> R:
        """The video renderer of ``cameras``: the last one, or a new one by ``make`` (the last
        one closed) when it draws other cameras."""
        if self._video is None or self._video.cfg.cameras != cameras:
            if self._video is not None:
                self._video.close()
            self._video = make()
        return self._video

    def close(self) -> None:
        """Closes the renderers (their GL contexts)."""
        for r in (self.renderer, self._video):
            if r is not None:
                r.close()
        self.renderer = self._video = None
