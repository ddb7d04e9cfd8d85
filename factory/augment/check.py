"""Physics verdicts of many configurations of one scene, in one batched call.

A configuration re-poses some free objects of a compiled model; its row of initial positions
``qpos0: (nq,)`` is the model's with those objects' free-joint entries replaced. Quaternions are
built by :meth:`factory.schema.Euler.quat_wxyz` from the same yaw (deg) the variant scene
stores, so a row equals the ``qpos0`` of the variant scene compiled on its own, bit for bit:
simulating the rows of the parent's model *is* the whole-scene check of each variant.

* :func:`judge_rows`: the rule of the whole-scene check for the free bodies of one model,
  typically the local scene of :mod:`factory.augment.local`: no free body starting more than
  the tolerance inside another object, then the strict protocol (no resettling) over the rows
  without collisions, in one batched call;
* :func:`verify_whole_scene`: the ordinary whole-scene check of ``stage=validate`` and
  :func:`factory.augment.stage.check_physics` (every object stable, no two objects
  interpenetrating deeper than the tolerance) for many variants of one scene at once;
* :func:`parent_verdict`: the same check of the parent as it stands, naming the objects that
  fail it.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np

from factory.schema import Euler, Scene
from factory.sim.backend import Backend, get_backend
from factory.sim.stability import (
    FreeBodies,
    StabilityProtocol,
    body_penetration,
    check_stability,
    rotation_angle_deg,
)


@dataclass(frozen=True)
class PhysicsCheck:
    """How augmentation judges poses in simulation.

    Attributes:
        assets_root: the run's ``assets/`` folder.
        backend: physics backend (instance or name: ``cpu``, ``warp``, ``mjx``, ``auto``).
        protocol: the stability thresholds, duration and timestep (``resettle`` and
            ``penetration_tol`` are set by each check).
        tol: collision tolerance (m): deeper initial interpenetration is a collision.
        context_margin: reach of the local scene's static context (m).
        batch_min: fewest rows simulated per batched check.
        batch_max: most rows simulated per batched check (bounds memory).
    """

    assets_root: Path
    backend: Backend | str = "cpu"
    protocol: StabilityProtocol = field(default_factory=StabilityProtocol)
    tol: float = 0.01
    context_margin: float = 0.3
    batch_min: int = 4
    batch_max: int = 4096

    @property
    def strict(self) -> StabilityProtocol:
        """The protocol of every check here, the whole-scene check's: no resettling; initial
        interpenetration is judged as a collision between objects (``tol``), not by the
        protocol."""
        return replace(self.protocol, resettle=False, penetration_tol=math.inf)

    def engine(self) -> Backend:
        """The backend instance."""
        return get_backend(self.backend) if isinstance(self.backend, str) else self.backend


def batch_sizes(backend_name: str) -> tuple[int, int]:
    """Default ``(batch_min, batch_max)`` rows per check: small batches on CPU cores (every row
    costs), large ones on a GPU (a launch costs about the same for one world or thousands)."""
    return (4, 4096) if backend_name == "cpu" else (2048, 8192)


def pose_rows(
    model: mujoco.MjModel, base: np.ndarray, ids: list[str], poses: np.ndarray
) -> np.ndarray:
    """Initial positions of configurations.

    Args:
        model: the compiled scene; ``ids`` are free bodies of it.
        base: ``(nq,)`` positions of everything else.
        ids: the ``k`` re-posed objects.
        poses: ``(n, k, 4)`` ``[x, y, z, yaw_deg]`` (bottom centre, world frame).

    Returns:
        ``(n, nq)`` rows.
    """
    free = FreeBodies.of(model)
    rows = np.tile(np.asarray(base, float), (len(poses), 1))
    for j, oid in enumerate(ids):
        adr = int(free.qposadr[free.index(oid)])
        rows[:, adr : adr + 3] = poses[:, j, :3]
        rows[:, adr + 3 : adr + 7] = [Euler(0.0, 0.0, float(a)).quat_wxyz() for a in poses[:, j, 3]]
    return rows


@dataclass
class RowVerdicts:
    """Per row: passed or why not.

    Attributes:
        ok: ``(n,)`` bool.
        reasons: ``n`` strings (empty where ``ok``): ``colliding: a|b``, ``invalid: ...``,
            ``unstable: <object>``.
        simulated: rows simulated (those without initial collisions).
        seconds: wall time of the simulation (s).
        wall_seconds: wall time of the whole check (s): contacts, simulation, verdicts.
    """

    ok: np.ndarray
    reasons: list[str]
    simulated: int = 0
    seconds: float = 0.0
    wall_seconds: float = 0.0

    def failures(self) -> dict[str, int]:
        """Failure counts by kind and object (``unstable: mug_0``)."""
        return dict(Counter(r.split(" by ")[0] for r in self.reasons if r))


def _collisions(
    model: mujoco.MjModel, rows: np.ndarray, bodies: np.ndarray, objects: np.ndarray, tol: float
) -> list[str]:
    """Per row, ``colliding: a|b`` where a body of ``bodies`` starts more than ``tol`` (m)
    inside a body of ``objects`` (MuJoCo's contacts after ``mj_forward``, the rule of
    :func:`factory.sim.stability.body_penetration` read as arrays), ``invalid: ...`` where
    MuJoCo fails, else empty."""
    data = mujoco.MjData(model)
    is_body = np.zeros(model.nbody, bool)
    is_body[bodies] = True
    is_obj = np.zeros(model.nbody, bool)
    is_obj[objects] = True
    out = [""] * len(rows)
    for i, q in enumerate(rows):
        if not np.isfinite(q).all():
            out[i] = "invalid: non-finite initial pose"
            continue
        data.qpos[:] = q
        data.qvel[:] = 0
        try:
            mujoco.mj_forward(model, data)
        except mujoco.FatalError as e:
            out[i] = f"invalid: MuJoCo error: {' '.join(str(e).split())}"
            continue
        if data.ncon == 0:
            continue
        depth = -np.asarray(data.contact.dist)
        pair = model.geom_bodyid[np.asarray(data.contact.geom)]
        for a, o in ((0, 1), (1, 0)):
            hit = (depth > tol) & is_body[pair[:, a]] & is_obj[pair[:, o]]
            if hit.any():
                k = int(np.argmax(np.where(hit, depth, -np.inf)))
                name = model.body(int(pair[k, o])).name or "world"
                out[i] = f"colliding: {model.body(int(pair[k, a])).name}|{name}"
                break
    return out


def _settle(
    model: mujoco.MjModel, rows: np.ndarray, check: PhysicsCheck
) -> tuple[np.ndarray, list[str], float]:
    """Simulates the rows from rest for the protocol's duration in one batched call and
    judges every free body by the protocol's rule, as :func:`check_stability` does without
    resettling (it is not called, to skip its per-row contact pass, which
    :func:`_collisions` has done).

    Returns:
        ``(n,)`` bool stable, ``n`` reasons (``invalid: ...``, ``unstable: <object>``, or
        empty), and the simulation's wall time (s).
    """
    protocol = check.strict
    base = protocol.apply(model)
    roll = check.engine().settle(base, rows, protocol.nstep(base))
    free = FreeBodies.of(base)
    with np.errstate(invalid="ignore"):
        trans = np.linalg.norm(free.positions(roll.qpos) - free.positions(rows), axis=-1)
        rot = rotation_angle_deg(free.quats(rows), free.quats(roll.qpos))
    stable_obj = (trans <= protocol.max_translation) & (rot <= protocol.max_rotation_deg)
    ok = stable_obj.all(axis=1) & ~roll.invalid
    moved = np.nan_to_num(trans, nan=np.inf) + 1e-3 * np.nan_to_num(rot, nan=np.inf)
    reasons = [""] * len(rows)
    for i in np.flatnonzero(~ok):
        if roll.invalid[i]:
            reasons[i] = f"invalid: {roll.reasons[i] or 'invalid simulation'}"
        else:
            reasons[i] = f"unstable: {free.names[int(np.argmax(moved[i]))]}"
    return ok, reasons, roll.seconds


def _judge(
    model: mujoco.MjModel,
    rows: np.ndarray,
    bodies: np.ndarray,
    objects: np.ndarray,
    check: PhysicsCheck,
) -> RowVerdicts:
    t0 = time.perf_counter()
    reasons = _collisions(model, rows, bodies, objects, check.tol)
    ok = np.zeros(len(rows), bool)
    run = np.array([i for i, r in enumerate(reasons) if not r], dtype=int)
    seconds = 0.0
    if len(run):
        ok[run], why, seconds = _settle(model, rows[run], check)
        for k, i in enumerate(run):
            reasons[i] = why[k]
    return RowVerdicts(ok, reasons, len(run), seconds, time.perf_counter() - t0)


def _object_bodies(model: mujoco.MjModel, objects: list[str]) -> np.ndarray:
    return np.array([model.body(o).id for o in objects], dtype=int)


def judge_rows(
    model: mujoco.MjModel, rows: np.ndarray, objects: list[str], check: PhysicsCheck
) -> RowVerdicts:
    """The verdict of each row of ``model`` (typically a local scene): no free body starts more
    than ``check.tol`` inside another object (the floor and walls do not count), then the rows
    without collisions simulated in one batched call, every free body stable by the strict
    protocol.

    Args:
        model: the compiled scene.
        rows: ``(n, nq)`` initial positions.
        objects: ids of the scene objects in ``model`` (the bodies collisions count against).
        check: backend and thresholds.
    """
    free = FreeBodies.of(model)
    return _judge(model, rows, free.body_ids, _object_bodies(model, objects), check)


def verify_whole_scene(
    scene: Scene, ids: list[str], poses: np.ndarray, check: PhysicsCheck
) -> RowVerdicts:
    """The whole-scene check of each configuration of ``scene``, batched.

    The same verdict as :func:`factory.augment.stage.check_physics` (and the per-object
    verdicts of ``stage=validate``) on the variant scene with ``ids`` at ``poses``: the
    whole scene compiled once, one row per variant; no object starts more than ``check.tol``
    inside another, every free object stable by the strict protocol.

    Args:
        scene: the parent scene (the ``ids`` at any pose).
        ids: the ``k`` re-posed objects.
        poses: ``(n, k, 4)`` ``[x, y, z, yaw_deg]``.
        check: backend, thresholds and assets.
    """
    from factory.sim.compile import compile_scene

    model = compile_scene(scene, check.assets_root).model
    rows = pose_rows(model, model.qpos0, ids, poses)
    bodies = _object_bodies(model, [o.id for o in scene.objects])
    return _judge(model, rows, bodies, bodies, check)


@dataclass(frozen=True)
class ParentVerdict:
    """The whole-scene check of a scene as it stands.

    Attributes:
        unstable: objects that are not stable (or all free objects, for an invalid simulation).
        colliding: ``"a|b"`` pairs of objects interpenetrating deeper than the tolerance.
        seconds: wall time (s).
    """

    unstable: tuple[str, ...]
    colliding: tuple[str, ...]
    seconds: float = 0.0

    def blocking(self, moving: set[str]) -> list[str]:
        """What fails whatever ``moving`` does: unstable objects outside it and collisions
        between two objects outside it."""
        out = [f"unstable: {o}" for o in self.unstable if o not in moving]
        out += [f"colliding: {p}" for p in self.colliding if not set(p.split("|")) & moving]
        return out


def parent_verdict(scene: Scene, check: PhysicsCheck) -> ParentVerdict:
    """The whole-scene check of ``scene`` at its own poses, per object.

    One simulation: it runs on the CPU backend (the reference) whatever ``check.backend`` is,
    since a GPU launch costs as much for one world as for thousands and would swap the GPU's
    model out for a single row."""
    from factory.sim.compile import compile_scene

    t0 = time.perf_counter()
    model = compile_scene(scene, check.assets_root).model
    rows = model.qpos0[None, :].copy()
    engine = check.engine()
    if engine.name != "cpu":
        engine = get_backend("cpu")
    result = check_stability(model, rows, backend=engine, protocol=check.strict)
    bodies = np.array([model.body(o.id).id for o in scene.objects], dtype=int)
    depth, pairs = body_penetration(model, rows, bodies, set(bodies.tolist()))
    unstable = [
        oid
        for j, oid in enumerate(result.object_ids)
        if result.invalid[0] or not result.stable_object[0, j]
    ]
    colliding = sorted({pairs[0][j] for j in np.flatnonzero(depth[0] > check.tol)})
    return ParentVerdict(tuple(unstable), tuple(colliding), time.perf_counter() - t0)
