"""Batched stability checks: the paper's physics protocol over many candidates at once.

Protocol (SAGE's): simulate each candidate from rest for ``duration`` (2.0 s) under gravity,
with the scene's friction and no artificial damping or velocity caps; an object is unstable if
it moved more than ``max_translation`` (0.2 m) or turned more than ``max_rotation_deg`` (8°).
A candidate is stable when every free object in it is stable and the simulation is valid.
The links of articulated objects (hinge and slide joints the compiler puts in
:data:`~factory.sim.compile.LINK_JOINT_GROUP`) are judged too, as objects named by their body
(``<object id>/<link>``): a closed door or drawer must stay closed and an ajar one where it is,
within ``max_link_rotation_deg`` (5°) or ``max_link_translation`` (2 cm).
With ``resettle`` (the paper's "settle and re-simulate" rule), an unstable candidate is
simulated again from its settled pose and accepted if that second run is stable.

Candidates are full initial positions ``qpos0: (n, nq)``; :func:`candidates_from_poses` builds
them from per-object poses. Candidates that start interpenetrating by more than
``penetration_tol`` are ``invalid`` (never stable), as are simulations that produced NaN or
overflowed a contact buffer.
"""

from __future__ import annotations

import copy
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from factory.cores import usable_cores
from factory.errors import ConfigError
from factory.sim.backend import Backend, get_backend

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StabilityProtocol:
    """Thresholds of the stability check.

    Attributes:
        duration: simulated time per candidate (s).
        max_translation: an object that moved farther is unstable (m).
        max_rotation_deg: an object that turned more is unstable (deg).
        penetration_tol: a candidate whose bodies start interpenetrating deeper is invalid (m).
        resettle: accept an unstable candidate whose settled pose is stable on a second run.
        timestep: simulation step for the check (s); ``None`` keeps the model's (2 ms).
        max_link_translation: a drawer (slide joint) that moved farther is unstable (m).
        max_link_rotation_deg: a door or lid (hinge joint) that turned more is unstable (deg).
    """

    duration: float = 2.0
    max_translation: float = 0.2
    max_rotation_deg: float = 8.0
    penetration_tol: float = 0.01
    resettle: bool = True
    timestep: float | None = None
    max_link_translation: float = 0.02
    max_link_rotation_deg: float = 5.0

    def nstep(self, model: mujoco.MjModel) -> int:
        return max(1, round(self.duration / model.opt.timestep))

    def apply(self, model: mujoco.MjModel) -> mujoco.MjModel:
        """``model``, or a copy of it with this protocol's timestep."""
        if self.timestep is None or self.timestep == model.opt.timestep:
            return model
        if not self.timestep > 0:
            raise ConfigError(f"sim.timestep must be > 0, got {self.timestep}")
        out = copy.copy(model)
        out.opt.timestep = self.timestep
        return out


@dataclass(frozen=True)
class FreeBodies:
    """The free-floating bodies of a model and where their poses sit in ``qpos``."""

    names: list[str]
    body_ids: np.ndarray
    qposadr: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel) -> FreeBodies:
        names, bodies, adrs = [], [], []
        for j in range(model.njnt):
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                b = int(model.jnt_bodyid[j])
                names.append(model.body(b).name)
                bodies.append(b)
                adrs.append(int(model.jnt_qposadr[j]))
        return cls(names, np.array(bodies, dtype=int), np.array(adrs, dtype=int))

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise ConfigError(
                f"{name!r} is not a free body of the model (free bodies: {self.names[:8]}...)"
            ) from None

    def positions(self, qpos: np.ndarray) -> np.ndarray:
        """``(n, k, 3)`` positions of the free bodies from ``qpos: (n, nq)``."""
        idx = self.qposadr[:, None] + np.arange(3)[None, :]
        return qpos[:, idx]

    def quats(self, qpos: np.ndarray) -> np.ndarray:
        """``(n, k, 4)`` orientations (w, x, y, z) of the free bodies."""
        idx = self.qposadr[:, None] + 3 + np.arange(4)[None, :]
        return qpos[:, idx]


@dataclass(frozen=True)
class LinkJoints:
    """The links of articulated objects: hinge and slide joints in
    :data:`~factory.sim.compile.LINK_JOINT_GROUP`, one per link body."""

    names: list[str]
    body_ids: np.ndarray
    qposadr: np.ndarray
    slide: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel) -> LinkJoints:
        from factory.sim.compile import LINK_JOINT_GROUP

        kinds = {int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)}
        js = [
            j
            for j in range(model.njnt)
            if int(model.jnt_type[j]) in kinds and model.jnt_group[j] == LINK_JOINT_GROUP
        ]
        bodies = np.array([model.jnt_bodyid[j] for j in js], dtype=int)
        return cls(
            [model.body(b).name for b in bodies],
            bodies,
            np.array([model.jnt_qposadr[j] for j in js], dtype=int),
            np.array([model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE for j in js], dtype=bool),
        )

    def moved(self, q0: np.ndarray, q1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(n, k)`` travel of the slides (m) and turn of the hinges (deg), 0 elsewhere."""
        d = np.abs(q1[:, self.qposadr] - q0[:, self.qposadr])
        return np.where(self.slide, d, 0.0), np.where(self.slide, 0.0, np.degrees(d))


@dataclass
class StabilityResult:
    """Per candidate ``i`` and free object ``j`` (``object_ids[j]``).

    Attributes:
        object_ids: the free objects, ``k`` of them.
        translation: ``(n, k)`` distance moved (m).
        rotation_deg: ``(n, k)`` angle turned (deg).
        stable_object: ``(n, k)`` bool, per the protocol.
        penetration: ``(n, k)`` deepest initial interpenetration of each object (m, >= 0).
        invalid: ``(n,)`` bool: NaN, overflow, MuJoCo error or initial interpenetration.
        reasons: ``n`` strings explaining ``invalid`` (empty where valid).
        resettled: ``(n,)`` bool: accepted by the settle-and-re-simulate rule.
        settled_qpos: ``(n, nq)`` positions at the end (of the second run if resettled).
        backend: the backend's name.
        seconds: simulation wall time (s).
    """

    object_ids: list[str]
    translation: np.ndarray
    rotation_deg: np.ndarray
    stable_object: np.ndarray
    penetration: np.ndarray
    invalid: np.ndarray
    reasons: list[str]
    resettled: np.ndarray
    settled_qpos: np.ndarray
    backend: str = "cpu"
    seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def stable(self) -> np.ndarray:
        """``(n,)`` bool: valid and every object stable in the first run (the strict verdict)."""
        return self.stable_object.all(axis=1) & ~self.invalid

    @property
    def accepted(self) -> np.ndarray:
        """``(n,)`` bool: stable, or accepted at its settled pose by the resettle rule."""
        return (self.stable | self.resettled) & ~self.invalid

    def rows(self, ids: np.ndarray | list[int]) -> StabilityResult:
        """The candidates ``ids`` only (a result of ``len(ids)`` candidates)."""
        ids = np.asarray(ids, dtype=int)
        return StabilityResult(
            object_ids=list(self.object_ids),
            translation=self.translation[ids],
            rotation_deg=self.rotation_deg[ids],
            stable_object=self.stable_object[ids],
            penetration=self.penetration[ids],
            invalid=self.invalid[ids],
            reasons=[self.reasons[i] for i in ids],
            resettled=self.resettled[ids],
            settled_qpos=self.settled_qpos[ids],
            backend=self.backend,
            seconds=self.seconds * len(ids) / max(1, len(self.invalid)),
            extra=dict(self.extra),
        )

    def candidate(self, i: int) -> dict[str, Any]:
        """One candidate's verdict as a JSON-ready dict."""
        return {
            "stable": bool(self.stable[i]),
            "accepted": bool(self.accepted[i]),
            "invalid": bool(self.invalid[i]),
            "reason": self.reasons[i],
            "resettled": bool(self.resettled[i]),
            "objects": {
                oid: {
                    "translation_m": float(self.translation[i, j]),
                    "rotation_deg": float(self.rotation_deg[i, j]),
                    "stable": bool(self.stable_object[i, j]),
                    "penetration_m": float(self.penetration[i, j]),
                }
                for j, oid in enumerate(self.object_ids)
            },
        }


def rotation_angle_deg(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Angle (deg) between unit quaternions ``(..., 4)``."""
    n0 = q0 / np.linalg.norm(q0, axis=-1, keepdims=True)
    n1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    dot = np.abs(np.sum(n0 * n1, axis=-1)).clip(0.0, 1.0)
    return np.degrees(2.0 * np.arccos(dot))


def body_penetration(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    bodies: np.ndarray,
    partners: set[int] | None = None,
) -> tuple[np.ndarray, list[list[str]]]:
    """Deepest interpenetration per body at each state (MuJoCo contacts, ``mj_forward``).

    Args:
        model: the model.
        qpos: ``(n, nq)`` states.
        bodies: ``(k,)`` body ids to report.
        partners: count only contacts with these bodies (default: any body, world included).

    Returns:
        ``(n, k)`` depths (m, >= 0; NaN where MuJoCo failed) and, per state, the names of the
        deepest pair (``"a|b"``) for each of the ``k`` bodies (empty if none; the error where
        MuJoCo failed).
    """
    n, k = len(qpos), len(bodies)
    depth = np.zeros((n, k))
    pairs: list[list[str]] = [[""] * k for _ in range(n)]
    slot = np.full(model.nbody, -1, dtype=int)
    slot[np.asarray(bodies, dtype=int)] = np.arange(k)
    allowed = np.ones(model.nbody, dtype=bool)
    if partners is not None:
        allowed[:] = False
        allowed[list(partners)] = True

    def name(b: int) -> str:
        return model.body(b).name or "world"

    def chunk(lo: int, hi: int) -> None:
        data = mujoco.MjData(model)
        for i in range(lo, hi):
            q = qpos[i]
            if not np.isfinite(q).all():
                continue
            data.qpos[:] = q
            data.qvel[:] = 0
            try:
                mujoco.mj_forward(model, data)
            except mujoco.FatalError as e:
                depth[i] = np.nan
                pairs[i] = [f"MuJoCo error: {' '.join(str(e).split())}"] * k
                continue
            if data.ncon == 0:
                continue
            con = data.contact
            pen = -np.asarray(con.dist[: data.ncon])
            ba = model.geom_bodyid[np.asarray(con.geom1[: data.ncon])]
            bb = model.geom_bodyid[np.asarray(con.geom2[: data.ncon])]
            for mine, other in ((ba, bb), (bb, ba)):
                j = slot[mine]
                use = (j >= 0) & (pen > 0) & allowed[other]
                for c in np.flatnonzero(use):
                    jj = j[c]
                    if pen[c] > depth[i, jj]:
                        depth[i, jj] = pen[c]
                        pairs[i][jj] = f"{name(int(mine[c]))}|{name(int(other[c]))}"

    threads = max(1, min(8, usable_cores(), n // 256))
    if threads == 1:
        chunk(0, n)
    else:  # mj_forward releases the GIL: chunks of candidates run side by side
        from concurrent.futures import ThreadPoolExecutor

        bounds = np.linspace(0, n, threads + 1).astype(int)
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(chunk, bounds[:-1], bounds[1:]))
    return depth, pairs


def candidates_from_poses(
    model: mujoco.MjModel,
    poses: Mapping[str, np.ndarray],
    base_qpos: np.ndarray | None = None,
) -> np.ndarray:
    """Builds ``qpos0: (n, nq)`` from per-object poses.

    Args:
        model: the compiled scene.
        poses: ``object id -> (n, 7)`` body poses ``[x, y, z, qw, qx, qy, qz]`` in the world
            frame (the body origin is the object's bottom centre); all of length ``n``.
        base_qpos: ``(nq,)`` positions of every other object (default ``model.qpos0``).
    """
    free = FreeBodies.of(model)
    lengths = {len(np.atleast_2d(p)) for p in poses.values()}
    if len(lengths) != 1:
        raise ConfigError(f"poses must all have the same number of candidates, got {lengths}")
    n = lengths.pop()
    base = model.qpos0 if base_qpos is None else np.asarray(base_qpos, float)
    q = np.tile(base, (n, 1))
    for name, pose in poses.items():
        p = np.atleast_2d(np.asarray(pose, float))
        if p.shape[1] != 7:
            raise ConfigError(f"pose of {name!r} must be (n, 7) [x y z qw qx qy qz]")
        adr = free.qposadr[free.index(name)]
        q[:, adr : adr + 7] = p
        norms = np.linalg.norm(p[:, 3:], axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            q[:, adr + 3 : adr + 7] = p[:, 3:] / norms
    return q


def _settle(
    engine: Backend,
    base: mujoco.MjModel,
    models: list[mujoco.MjModel] | None,
    idx: np.ndarray,
    qpos: np.ndarray,
    nstep: int,
) -> Any:
    target = base if models is None else [models[i] for i in idx]
    return engine.settle(target, qpos, nstep)


def _evaluate(
    free: FreeBodies,
    links: LinkJoints,
    q0: np.ndarray,
    q1: np.ndarray,
    protocol: StabilityProtocol,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    with np.errstate(invalid="ignore"):
        trans = np.linalg.norm(free.positions(q1) - free.positions(q0), axis=-1)
        rot = rotation_angle_deg(free.quats(q0), free.quats(q1))
        slid, turned = links.moved(q0, q1)
    stable = (trans <= protocol.max_translation) & (rot <= protocol.max_rotation_deg)
    held = (slid <= protocol.max_link_translation) & (turned <= protocol.max_link_rotation_deg)
    trans, rot = np.hstack([trans, slid]), np.hstack([rot, turned])
    stable = np.hstack([stable, held])
    return np.nan_to_num(trans, nan=np.inf), np.nan_to_num(rot, nan=np.inf), stable


def check_stability(
    model: mujoco.MjModel | Sequence[mujoco.MjModel],
    qpos0: np.ndarray | None = None,
    *,
    backend: str | Backend = "cpu",
    protocol: StabilityProtocol | None = None,
) -> StabilityResult:
    """Simulates every candidate and judges it by the protocol.

    Args:
        model: the compiled scene, or one model per candidate (same layout: e.g. variants of
            a scene compiled from one spec).
        qpos0: ``(n, nq)`` initial positions; default: the model's own (one candidate).
        backend: ``cpu``, ``warp``, ``mjx``, ``auto`` or a backend instance.
        protocol: thresholds (default: the paper's).

    Returns:
        the per-candidate, per-object verdicts.

    Raises:
        ConfigError: an empty batch or a wrong shape.
    """
    protocol = protocol or StabilityProtocol()
    models = None if isinstance(model, mujoco.MjModel) else [protocol.apply(m) for m in model]
    base = protocol.apply(model) if models is None else models[0]
    assert isinstance(base, mujoco.MjModel)
    q0 = np.atleast_2d(base.qpos0.copy() if qpos0 is None else np.asarray(qpos0, float))
    if q0.shape[0] == 0:
        raise ConfigError("the candidate batch is empty: pass at least one candidate")
    if q0.shape[1] != base.nq:
        raise ConfigError(f"qpos0 must be (n, {base.nq}), got {q0.shape}")
    engine = get_backend(backend) if isinstance(backend, str) else backend
    free = FreeBodies.of(base)
    links = LinkJoints.of(base)
    n = len(q0)

    penetration, pairs = body_penetration(base, q0, np.concatenate([free.body_ids, links.body_ids]))
    invalid = ~np.isfinite(q0).all(axis=1)
    reasons = ["non-finite initial pose" if bad else "" for bad in invalid]
    failed = np.isnan(penetration).any(axis=1) & ~invalid
    for i in np.flatnonzero(failed):
        invalid[i] = True
        reasons[i] = pairs[i][0] if pairs[i] else "MuJoCo error"
    penetration = np.nan_to_num(penetration, nan=0.0)
    deep = penetration > protocol.penetration_tol
    for i in np.flatnonzero(deep.any(axis=1) & ~invalid):
        j = int(np.argmax(penetration[i]))
        invalid[i] = True
        reasons[i] = (
            f"starts interpenetrating: {pairs[i][j]} by {penetration[i, j] * 100:.1f} cm "
            f"(> {protocol.penetration_tol * 100:.1f} cm)"
        )

    nstep = protocol.nstep(base)
    run = np.flatnonzero(~invalid)
    q1 = q0.copy()
    seconds = 0.0
    if len(run):
        roll = _settle(engine, base, models, run, q0[run], nstep)
        q1[run] = roll.qpos
        seconds += roll.seconds
        for k, i in enumerate(run):
            if roll.invalid[k]:
                invalid[i] = True
                reasons[i] = roll.reasons[k] or "invalid simulation"
    trans, rot, stable_obj = _evaluate(free, links, q0, q1, protocol)
    stable_obj &= ~invalid[:, None]

    resettled = np.zeros(n, bool)
    settled = q1.copy()
    if protocol.resettle:
        again = np.flatnonzero(~invalid & ~stable_obj.all(axis=1))
        if len(again):
            roll2 = _settle(engine, base, models, again, q1[again], nstep)
            seconds += roll2.seconds
            _, _, stable2 = _evaluate(free, links, q1[again], roll2.qpos, protocol)
            ok = stable2.all(axis=1) & ~roll2.invalid
            resettled[again[ok]] = True
            settled[again] = roll2.qpos
    return StabilityResult(
        object_ids=[*free.names, *links.names],
        translation=trans,
        rotation_deg=rot,
        stable_object=stable_obj,
        penetration=penetration,
        invalid=invalid,
        reasons=reasons,
        resettled=resettled,
        settled_qpos=settled,
        backend=engine.name,
        seconds=seconds,
    )


def summary(result: StabilityResult) -> dict[str, Any]:
    """Counts over a batch: candidates, stable, invalid, resettled, worst object."""
    n = len(result.invalid)
    worst = {}
    if result.translation.size:
        finite = np.where(np.isfinite(result.translation), result.translation, -1.0)
        i, j = np.unravel_index(np.argmax(finite), finite.shape)
        worst = {
            "object": result.object_ids[j],
            "translation_m": float(result.translation[i, j]),
        }
    return {
        "candidates": n,
        "stable": int(result.stable.sum()),
        "accepted": int(result.accepted.sum()),
        "invalid": int(result.invalid.sum()),
        "resettled": int(result.resettled.sum()),
        "stable_ratio": float(result.stable.mean()) if n else math.nan,
        "worst": worst,
        "backend": result.backend,
        "seconds": result.seconds,
    }
