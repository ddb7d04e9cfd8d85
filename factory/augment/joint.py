"""Joint placement: poses for several objects at once, many candidates per batched check.

Instead of placing objects one after the other with a few candidates per physics call, the
objects to pose (*movers*, each on its current support) are sampled together: many joint
configurations are drawn (:mod:`factory.augment.sampling`), the footprint-free ones that are
distinct from what is already kept (:mod:`factory.augment.distinct`) become rows of one
compiled model (the local scene of :mod:`factory.augment.local`), and one batched call of the
physics backend judges them all (:func:`factory.augment.check.judge_rows`). Rounds repeat
until ``count`` distinct valid configurations are kept; a round's size follows the acceptance
seen so far (at least ``batch_min``, at most ``batch_max`` rows), so the work stays close to
what the count needs on CPU cores and fills a GPU in one call. Everything depends only on the
scene, the seed and the options: the same inputs give the same configurations.
"""

from __future__ import annotations

import logging
import math
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.augment.check import PhysicsCheck, judge_rows, pose_rows
from factory.augment.distinct import Distinctness
from factory.augment.local import local_scene
from factory.augment.sampling import movers_of, sample
from factory.errors import FactoryError
from factory.scenes.placement import SceneState

log = logging.getLogger(__name__)


class PlacementError(FactoryError):
    """No footprint-free configuration of the movers exists (nothing was simulated)."""


@dataclass(frozen=True)
class JointOptions:
    """How many configurations and how hard to look.

    Attributes:
        count: distinct valid configurations wanted.
        distinct: when two configurations differ.
        max_rounds: batched checks at most.
        oversample: configurations drawn per row simulated, at least (more where the
            footprint test failed often in earlier rounds, up to 64).
        prior_acceptance: assumed share of valid rows before any is seen.
    """

    count: int = 1
    distinct: Distinctness = field(default_factory=Distinctness)
    max_rounds: int = 6
    oversample: int = 2
    prior_acceptance: float = 0.95


@dataclass
class JointPlacement:
    """What :func:`place_jointly` kept.

    Attributes:
        ids: the ``k`` movers.
        poses: ``(m, k, 4)`` ``[x, y, z, yaw_deg]`` of the kept configurations (``m <= count``),
            in the order found.
        stats: counts (drawn, footprint-free, checked, simulated, valid, kept, rounds),
            timings (s) and failure reasons, JSON-ready.
    """

    ids: list[str]
    poses: np.ndarray
    stats: dict[str, Any]


def _rows_for(need: int, valid: int, simulated: int, opts: JointOptions, lo: int, hi: int) -> int:
    prior = 4.0
    rate = (valid + prior * opts.prior_acceptance) / (simulated + prior)
    return int(min(hi, max(lo, math.ceil(need / max(rate, 0.02)))))


def place_jointly(
    state: SceneState,
    ids: list[str],
    check: PhysicsCheck | None,
    rng: np.random.Generator,
    options: JointOptions | None = None,
    exclude: np.ndarray | None = None,
) -> JointPlacement:
    """Distinct valid joint configurations of ``ids`` on their supports.

    Args:
        state: the scene with the movers in it (at any pose) and the assets of their supports
            in ``state.metas``; not modified.
        ids: the movers (free objects, each ``on_top`` of a support that does not move).
        check: physics settings; ``None`` keeps footprint-free configurations unsimulated.
        rng: the source of every draw.
        options: count, distinctness, effort.
        exclude: ``(e, k, 4)`` configurations the results must differ from (the parent's).

    Returns:
        up to ``options.count`` configurations (fewer when the rounds ran out).

    Raises:
        PlacementError: no footprint-free configuration in the first round.
        SamplingError: a mover fits on no surface of its support.
    """
    opts = options or JointOptions()
    movers = movers_of(state, ids)
    k = len(ids)
    kept = np.zeros((0, k, 4))
    prior = np.zeros((0, k, 4)) if exclude is None else np.asarray(exclude, float)
    stats: Counter[str] = Counter()
    failures: Counter[str] = Counter()
    timing = {"sample": 0.0, "compile": 0.0, "check": 0.0, "simulate": 0.0}
    model = None
    lo, hi = (check.batch_min, check.batch_max) if check else (opts.count, opts.count)
    for rnd in range(opts.max_rounds):
        need = opts.count - len(kept)
        if need <= 0:
            break
        rows = _rows_for(need, stats["valid"], stats["checked"], opts, lo, hi)
        t0 = time.perf_counter()
        share = (stats["footprint_free"] + 1) / (stats["drawn"] + 1) if stats["drawn"] else 1.0
        draws = min(64, max(opts.oversample, math.ceil(1.25 / share))) * rows
        drawn = sample(movers, draws, rng)
        free = np.flatnonzero(drawn.free)
        pick = free[opts.distinct.select(drawn.pose[free], np.concatenate([prior, kept]), rows)]
        timing["sample"] += time.perf_counter() - t0
        stats["drawn"] += len(drawn.free)
        stats["footprint_free"] += len(free)
        stats["rounds"] = rnd + 1
        if len(pick) == 0:
            if rnd == 0 and len(free) == 0:
                raise PlacementError(
                    f"no footprint-free configuration of {', '.join(ids)} in "
                    f"{len(drawn.free)} draws: their supports are too crowded"
                )
            continue
        poses = drawn.pose[pick]
        if check is None:
            ok = np.ones(len(pick), bool)
        else:
            if model is None:
                from factory.sim.compile import compile_scene

                t0 = time.perf_counter()
                local = local_scene(state.scene, ids, check.context_margin)
                model = compile_scene(local.scene, check.assets_root).model
                objects = [o.id for o in local.scene.objects]
                timing["compile"] += time.perf_counter() - t0
                stats["local_dynamic"] = len(local.dynamic)
                stats["local_context"] = len(local.context)
                stats["local_absent"] = len(local.absent)
            verdict = judge_rows(model, pose_rows(model, model.qpos0, ids, poses), objects, check)
            ok = verdict.ok
            timing["check"] += verdict.wall_seconds
            timing["simulate"] += verdict.seconds
            failures.update(verdict.failures())
            stats["checked"] += len(pick)
            stats["simulated"] += verdict.simulated
        stats["valid"] += int(ok.sum())
        kept = np.concatenate([kept, poses[ok][:need]])
    stats["kept"] = len(kept)
    out: dict[str, Any] = dict(stats)
    out["seconds"] = {key: round(v, 4) for key, v in timing.items()}
    out["failures"] = dict(failures.most_common(8))
    log.debug("joint placement of %s: %s", ids, out)
    return JointPlacement(list(ids), kept, out)
