"""Object placement: floor (grid sampling + depth-first search with collision checks), wall
mounts, and on-top placement on any support surface (multi-level), with the physics critic.

Conventions: an object's front faces its local -y, its back +y; "against a wall" turns the back
to the wall. Candidate positions are sampled on a grid, scored by the rule, and searched in
score order (depth-first: the first collision-free candidate wins; on-top candidates go to the
physics critic in small batches, first stable one accepted).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.assets import AssetLibrary, Resolution
from factory.nav.support_gap import footprint_gap
from factory.scenes.footprint import Footprint, inside, overlaps
from factory.schema import (
    AssetMeta,
    AssetRef,
    Euler,
    Physics,
    Placement,
    Room,
    Scene,
    SceneObject,
    Size3,
    Vec3,
)

log = logging.getLogger(__name__)

WALL_GAP = 0.01
CLEARANCE = 0.02
DOOR_DEPTH = 0.9
AWAY_DISTANCE = 2.5
"""Distance (m) from the target that the ``facing`` and ``away`` floor rules aim at (the
mobile task's place support from the pick's support: at least 1.5 m is required)."""
AWAY_GAP = 2.2
"""Gap (m) between the footprints' nearest edges that the ``away`` rule aims at: the mobile
task's place support out of reach of the pick's base pose (at least
:data:`~factory.nav.support_gap.MIN_SUPPORT_GAP`, 2.0 m, is required at generation)."""


@dataclass
class PlaceResult:
    """What a placement did (JSON-ready through :meth:`as_dict`)."""

    ok: bool
    object_id: str | None = None
    reason: str = ""
    candidates: int = 0
    detail: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "ok": self.ok,
            "object_id": self.object_id,
            "reason": self.reason,
            "candidates": self.candidates,
            **self.detail,
        }


class SceneState:
    """A scene under construction, with the assets of its objects.

    Args:
        scene: the scene (rooms set up; objects may already exist).
        library: where assets come from.
        seed: random seed of sampling.
    """

    def __init__(self, scene: Scene, library: AssetLibrary, seed: int = 0) -> None:
        self.scene = scene
        self.library = library
        self.rng = np.random.default_rng(seed)
        self.metas: dict[str, AssetMeta] = {}
        self.counts: dict[str, int] = {}
        self.reuse: tuple[AssetMeta, Resolution] | None = None

    # ---- geometry helpers
    def room(self, room_id: str | None = None) -> Room:
        return self.scene.room(room_id) if room_id else self.scene.rooms[0]

    def interior(self, room: Room) -> tuple[float, float, float, float]:
        t = max((w.thickness for w in room.walls), default=0.1) / 2
        x0, y0 = room.position.x, room.position.y
        return (x0 + t, y0 + t, x0 + room.dimensions.width - t, y0 + room.dimensions.length - t)

    def footprint(self, obj: SceneObject) -> Footprint:
        d = obj.dimensions
        return Footprint(
            obj.position.x,
            obj.position.y,
            d.width / 2,
            d.length / 2,
            math.radians(obj.rotation.z),
            obj.position.z,
            obj.position.z + d.height,
        )

    def new_id(self, category: str) -> str:
        n = self.counts.get(category, 0)
        existing = {o.id for o in self.scene.objects}
        while f"{category}_{n}" in existing:
            n += 1
        self.counts[category] = n + 1
        return f"{category}_{n}"

    @staticmethod
    def _opening_zones(
        room: Room, openings: list[Any], depth: float, z: Any, widen: float = 0.0
    ) -> list[Footprint]:
        """Footprints centred on openings of the room's walls (``z(opening) -> (z0, z1)``)."""
        zones = []
        walls = {w.id: w for w in room.walls}
        for op in openings:
            w = walls[op.wall_id]
            t = op.position_on_wall
            cx = w.start.x + (w.end.x - w.start.x) * t
            cy = w.start.y + (w.end.y - w.start.y) * t
            yaw = math.atan2(w.end.y - w.start.y, w.end.x - w.start.x)
            z0, z1 = z(op)
            zones.append(Footprint(cx, cy, op.width / 2 + widen, depth, yaw, z0, z1))
        return zones

    def door_zones(self, room: Room) -> list[Footprint]:
        """Rectangles in front of (both sides of) each door that must stay free."""
        return self._opening_zones(room, list(room.doors), DOOR_DEPTH, lambda d: (0.0, 2.5), 0.1)

    def window_zones(self, room: Room) -> list[Footprint]:
        """Thin boxes in front of windows, from sill to top, that tall furniture must not block."""
        return self._opening_zones(
            room, list(room.windows), 0.25, lambda w: (w.sill_height, w.sill_height + w.height)
        )

    def free(
        self, fp: Footprint, room: Room, ignore: set[str] | None = None, on: str | None = None
    ) -> bool:
        """Whether ``fp`` collides with nothing (objects, door and window zones)."""
        for obj in self.scene.objects:
            if ignore and obj.id in ignore:
                continue
            if on is not None and obj.placement.support_id != on:
                continue
            if on is None and obj.placement.kind == "on_top":
                continue
            if overlaps(fp, self.footprint(obj), CLEARANCE if on is None else 0.005):
                return False
        if on is None:
            for zone in self.door_zones(room):
                if overlaps(fp, zone):
                    return False
            for zone in self.window_zones(room):
                if fp.z1 > zone.z0 + 0.05 and overlaps(fp, zone):
                    return False
        return True

    # ---- assets
    def asset(self, text: str, dims: Any = None) -> tuple[AssetMeta, Resolution]:
        """The asset for the next placement: ``reuse`` (set by the caller, used once) or a new
        one from the library, weathered and finished by the scene request's condition words
        ("a dusty attic": every new object is dusty)."""
        from factory.scenes.request import parse_request

        seed = int(self.rng.integers(0, 2**31))
        if self.reuse is not None:
            pinned, self.reuse = self.reuse, None
            return pinned
        finish = parse_request(self.scene.description).conditions if self.scene.description else ()
        if finish:
            return self.library.from_text(text, seed=seed, dims=dims, finish=finish)
        return self.library.from_text(text, seed=seed, dims=dims)

    def meta_of(self, obj: SceneObject) -> tuple[AssetMeta, Resolution]:
        """An existing object's asset (from the cache) with a resolution naming its category."""
        from factory.assets import AssetSpec
        from factory.schema import load_asset_meta

        if obj.id in self.metas:
            meta = self.metas[obj.id]
        elif obj.asset is not None and obj.asset.asset_id:
            meta = load_asset_meta(self.library.assets_dir / obj.asset.asset_id)
        else:
            raise ValueError(f"object {obj.id!r} has no asset in {self.library.assets_dir}")
        spec = AssetSpec(obj.category, text=obj.description or obj.category)
        return meta, Resolution(spec, 1.0, False, obj.category)

    def add(
        self,
        meta: AssetMeta,
        res: Resolution,
        room: Room,
        pos: tuple[float, float, float],
        yaw: float,
        placement: Placement,
        static: bool = False,
        task_role: str | None = None,
    ) -> SceneObject:
        obj = SceneObject(
            id=self.new_id(res.spec.category),
            room_id=room.id,
            category=res.spec.category,
            description=res.spec.text,
            position=Vec3(*(float(v) for v in pos)),
            rotation=Euler(0.0, 0.0, float(math.degrees(yaw))),
            dimensions=Size3(*(float(v) for v in meta.extents)),
            placement=placement,
            asset=AssetRef(backend=meta.backend, asset_id=meta.asset_id),
            physics=Physics(
                mass=float(meta.mass or 1.0),
                friction=float(meta.friction or 0.6),
                static=static or _fixed(res.spec.category),
            ),
            license=meta.license,
            task_role=task_role,
        )
        self.scene.objects.append(obj)
        self.metas[obj.id] = meta
        return obj


# ---- floor


_WALL_YAWS = {"south": math.pi, "north": 0.0, "east": -math.pi / 2, "west": math.pi / 2}


def _wall_candidates(
    state: SceneState, room: Room, w: float, ln: float, step: float
) -> list[tuple[float, float, float, str, float]]:
    """``(x, y, yaw, side, along)`` with the back against each wall of the room."""
    x0, y0, x1, y1 = state.interior(room)
    out = []
    for side, yaw in _WALL_YAWS.items():
        horizontal = side in ("south", "north")
        lo, hi = (x0 + w / 2, x1 - w / 2) if horizontal else (y0 + w / 2, y1 - w / 2)
        if hi < lo:
            continue
        n = max(1, int((hi - lo) / step) + 1)
        for along in np.linspace(lo, hi, n):
            if side == "south":
                out.append(
                    (along, y0 + ln / 2 + WALL_GAP, yaw, side, (along - lo) / max(hi - lo, 1e-9))
                )
            elif side == "north":
                out.append(
                    (along, y1 - ln / 2 - WALL_GAP, yaw, side, (along - lo) / max(hi - lo, 1e-9))
                )
            elif side == "east":
                out.append(
                    (x1 - ln / 2 - WALL_GAP, along, yaw, side, (along - lo) / max(hi - lo, 1e-9))
                )
            else:
                out.append(
                    (x0 + ln / 2 + WALL_GAP, along, yaw, side, (along - lo) / max(hi - lo, 1e-9))
                )
    return out


def place_floor(
    state: SceneState,
    text: str,
    rule: str = "wall",
    room_id: str | None = None,
    target: str | None = None,
    task_role: str | None = None,
    dims: Any = None,
) -> PlaceResult:
    """Places a floor object by ``rule`` (``wall``, ``corner``, ``free``, ``center``,
    ``near``, ``around``, ``facing``, ``away``; ``target`` names the object for the last
    four). ``facing``: against a wall, its front turned to the target, about
    :data:`AWAY_DISTANCE` from it where it can; ``away``: anywhere free, as near to
    :data:`AWAY_DISTANCE` from the target as it can, its front turned to it."""
    room = state.room(room_id)
    meta, res = state.asset(text, dims)
    w, ln, h = meta.extents
    rng = state.rng
    cands: list[tuple[float, float, float, float]] = []  # score, x, y, yaw
    x0, y0, x1, y1 = state.interior(room)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    tgt = state.scene.object(target) if target else None
    if rule in ("wall", "corner"):
        for x, y, yaw, _side, along in _wall_candidates(state, room, w, ln, 0.1):
            if rule == "corner":
                score = -min(along, 1 - along)
            else:
                score = -abs(along - 0.5) * (2.0 if w > 1.2 else 0.3) + rng.uniform(0, 0.4)
            cands.append((score, x, y, yaw))
    elif rule == "facing" and tgt is not None:
        # along the walls or in free space, turned so that the front (-y) looks at the target
        for x, y, _yaw, _side, _along in _wall_candidates(state, room, w, ln, 0.1):
            dx, dy = tgt.position.x - x, tgt.position.y - y
            yaw = math.atan2(dx, -dy)  # local -y -> (dx, dy)
            dist = math.hypot(dx, dy)
            cands.append((-abs(dist - AWAY_DISTANCE) + rng.uniform(0, 0.2), x, y, yaw))
    elif rule == "away" and tgt is not None:
        # anywhere free, about AWAY_GAP between the edges, turned to face the target
        tfp = state.footprint(tgt)
        tbox = (tfp.x, tfp.y, tfp.hx, tfp.hy, tfp.yaw)
        for gx in np.arange(x0 + 0.3, x1 - 0.3 + 1e-9, 0.2):
            for gy in np.arange(y0 + 0.3, y1 - 0.3 + 1e-9, 0.2):
                dx, dy = tgt.position.x - float(gx), tgt.position.y - float(gy)
                yaw = math.atan2(dx, -dy)
                gap = footprint_gap((float(gx), float(gy), w / 2, ln / 2, yaw), tbox)
                score = -abs(gap - AWAY_GAP) + rng.uniform(0, 0.2)
                cands.append((score, float(gx), float(gy), yaw))
    elif rule == "near" and tgt is not None:
        tfp = state.footprint(tgt)
        c, s = math.cos(tfp.yaw), math.sin(tfp.yaw)
        for side in (-1, 1):
            off = tfp.hx + w / 2 + 0.05
            back = tfp.hy - ln / 2  # keep the back flush with the target's back
            bx = tgt.position.x + side * off * c - back * s
            by = tgt.position.y + side * off * s + back * c
            cands.append((1.0 + rng.uniform(0, 0.1), bx, by, tfp.yaw))
    elif rule == "around" and tgt is not None:
        tfp = state.footprint(tgt)
        c, s = math.cos(tfp.yaw), math.sin(tfp.yaw)
        for k in range(4):
            ang = tfp.yaw + k * math.pi / 2
            half_t = tfp.hy if k % 2 == 0 else tfp.hx
            half_side = tfp.hx if k % 2 == 0 else tfp.hy
            dist = half_t + ln / 2 + 0.06 + 2 * CLEARANCE
            nx, ny = -math.sin(ang), math.cos(ang)  # outward normal of that side
            n_slots = max(1, int((2 * half_side) // (w + 0.1)))
            for j in range(n_slots):
                t = (j + 0.5) / n_slots * 2 - 1
                px = tgt.position.x + nx * dist + math.cos(ang) * t * (half_side - w / 2)
                py = tgt.position.y + ny * dist + math.sin(ang) * t * (half_side - w / 2)
                yaw = ang  # the chair's back (+y) points away from the table
                cands.append((1.0 - 0.1 * k + rng.uniform(0, 0.05), px, py, yaw))
        del c, s
    else:  # free / center
        step = 0.2
        for gx in np.arange(x0 + 0.3, x1 - 0.3 + 1e-9, step):
            for gy in np.arange(y0 + 0.3, y1 - 0.3 + 1e-9, step):
                x, y = float(gx), float(gy)
                d = math.hypot(x - cx, y - cy)
                score = -d if rule == "center" else rng.uniform(0, 1)
                yaw = float(rng.choice([0, math.pi / 2, math.pi, -math.pi / 2]))
                if rule == "center":
                    yaw = 0.0 if (x1 - x0) >= (y1 - y0) or w < ln else math.pi / 2
                cands.append((score, x, y, yaw))
    cands.sort(key=lambda c: -c[0])
    for _score, x, y, yaw in cands:
        fp = Footprint(x, y, w / 2, ln / 2, yaw, 0.0, h)
        if not inside(fp, (x0, y0, x1, y1), -1e-6) or not state.free(fp, room):
            continue
        obj = state.add(meta, res, room, (x, y, 0.0), yaw, Placement("floor"), task_role=task_role)
        return PlaceResult(True, obj.id, candidates=len(cands))
    return PlaceResult(
        False, None, f"no free floor space for {text!r} ({rule})", candidates=len(cands)
    )


def place_wall(
    state: SceneState, text: str, height: float = 1.3, room_id: str | None = None
) -> PlaceResult:
    """Mounts an object on a wall with its bottom at ``height`` (m); static in simulation."""
    room = state.room(room_id)
    meta, res = state.asset(text)
    w, ln, h = meta.extents
    top = min(height + h, room.ceiling_height - 0.05)
    z0 = top - h
    cands = _wall_candidates(state, room, w, ln, 0.1)
    order = state.rng.permutation(len(cands))
    walls = {"south": "south", "north": "north", "east": "east", "west": "west"}
    for i in order:
        x, y, yaw, side, _ = cands[int(i)]
        fp = Footprint(x, y, w / 2, ln / 2, yaw, z0, z0 + h)
        if not state.free(fp, room):
            continue
        wall_id = next((wl.id for wl in room.walls if wl.id.endswith(walls[side])), None)
        obj = state.add(
            meta, res, room, (x, y, z0), yaw, Placement("wall", support_id=wall_id), static=True
        )
        return PlaceResult(True, obj.id, candidates=len(cands))
    return PlaceResult(False, None, f"no free wall space for {text!r}", candidates=len(cands))


# ---- on top


def support_rects(
    state: SceneState, obj: SceneObject, interiors: bool = True, only_interiors: bool = False
) -> list[tuple[str, float, np.ndarray, float]]:
    """``(name, z_world, corners (4, 2) world, clearance)`` of the object's support surfaces;
    without ``interiors``, not those behind a door or in a drawer (an articulated asset's
    supports with ``access``: the joint to open first); with ``only_interiors``, only those."""
    meta = state.metas.get(obj.id)
    if meta is None:
        return []
    yaw = math.radians(obj.rotation.z)
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    out = []
    for sup in meta.supports:
        if not interiors and sup.get("access"):
            continue
        if only_interiors and not sup.get("access"):
            continue
        x0, y0, x1, y1 = sup["rect"]
        local = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)
        world = local @ rot.T + [obj.position.x, obj.position.y]
        out.append(
            (
                sup["name"],
                obj.position.z + float(sup["z"]),
                world,
                float(sup.get("clearance", 10.0)),
            )
        )
    return out


def on_top_candidates(
    state: SceneState,
    support: SceneObject,
    w: float,
    ln: float,
    h: float,
    n: int = 24,
    interiors: bool = True,
    only_interiors: bool = False,
) -> list[tuple[float, float, float, float, str]]:
    """``(x, y, z, yaw, surface)`` candidates fully on a surface, free of other objects there
    (``interiors``: surfaces behind doors and in drawers too; ``only_interiors``: only those;
    :func:`support_rects`).

    The turn is drawn first (aligned with the support, a quarter turn, or a little askew); the
    position is then drawn where that footprint fits on the surface.
    """
    room = state.room(support.room_id)
    out = []
    rng = state.rng
    yaw0 = math.radians(support.rotation.z)
    for name, z, corners, clearance in support_rects(state, support, interiors, only_interiors):
        if h > clearance - 0.01:
            continue  # does not fit under the next board
        ux, uy = corners[1] - corners[0], corners[3] - corners[0]
        su, sv = float(np.linalg.norm(ux)), float(np.linalg.norm(uy))
        if su < 1e-6 or sv < 1e-6:
            continue
        eu, ev = ux / su, uy / sv
        for _ in range(n):
            rel = float(rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2]))
            if rng.uniform() < 0.4:
                rel += float(rng.uniform(-0.3, 0.3))
            c, s = abs(math.cos(rel)), abs(math.sin(rel))
            half_u = (w * c + ln * s) / 2 + 0.01
            half_v = (w * s + ln * c) / 2 + 0.01
            if 2 * half_u > su or 2 * half_v > sv:
                continue
            a = rng.uniform(half_u, su - half_u)
            b = rng.uniform(half_v, sv - half_v)
            x, y = corners[0] + a * eu + b * ev
            yaw = yaw0 + rel
            fp = Footprint(float(x), float(y), w / 2, ln / 2, yaw, z, z + h)
            if not state.free(fp, room, on=support.id):
                continue
            out.append((float(x), float(y), z, yaw, name))
    return out


def _euler(qw: float, qx: float, qy: float, qz: float) -> Euler:
    from scipy.spatial.transform import Rotation

    ax, ay, az = Rotation.from_quat([qx, qy, qz, qw]).as_euler("xyz", degrees=True)
    return Euler(float(ax), float(ay), float(az))


def _edge_distance(fp: Footprint, x: float, y: float) -> float:
    """Distance (m) from a point to the nearest side of a footprint (inside: positive)."""
    c, s = math.cos(fp.yaw), math.sin(fp.yaw)
    lx = (x - fp.x) * c + (y - fp.y) * s
    ly = -(x - fp.x) * s + (y - fp.y) * c
    return min(fp.hx - abs(lx), fp.hy - abs(ly))


def place_on(
    state: SceneState,
    text: str,
    support_id: str,
    critic: Any = None,
    task_role: str | None = None,
    batch: int = 4,
    max_batches: int = 3,
    dims: Any = None,
    inside: bool = False,
) -> PlaceResult:
    """Places an object on a support surface of ``support_id`` (any level: tops, boards,
    seats, or inside a vessel), checking candidates with the physics critic in batches;
    ``inside``: only on its interiors (behind a door, in a drawer), never a task's object."""
    support = state.scene.object(support_id)
    meta, res = state.asset(text, dims)
    w, ln, h = meta.extents
    if inside and task_role is not None:
        raise ValueError(
            f"a task's {task_role!r} object is not stored inside {support_id}: place it on_top"
        )
    # stored inside (behind a door, in a drawer): small things, never a task's objects
    cands = on_top_candidates(
        state,
        support,
        w,
        ln,
        h,
        interiors=inside or (task_role is None and _storable(meta.category)),
        only_interiors=inside,
    )
    if task_role is not None:
        # task objects go near the edge of the surface facing the room, reachable for a robot
        sup_fp = state.footprint(support)
        cands.sort(key=lambda c: _edge_distance(sup_fp, c[0], c[1]))
    if not cands:
        where = "free surface inside" if inside else "free surface on"
        return PlaceResult(False, None, f"no {where} {support_id} for {text!r}")
    room = state.room(support.room_id)
    obj = state.add(
        meta,
        res,
        room,
        cands[0][:3],
        cands[0][3],
        Placement("on_top", support_id=support_id),
        task_role=task_role,
    )
    if critic is None:
        return PlaceResult(True, obj.id, candidates=len(cands))
    failures: list[Any] = []
    for k in range(min(max_batches, math.ceil(len(cands) / batch))):
        chunk = cands[k * batch : (k + 1) * batch]
        poses = [[x, y, z, math.degrees(yaw)] for x, y, z, yaw, _ in chunk]
        verdict = critic(state.scene, obj.id, poses)
        if verdict["ok"]:
            x, y, z, yaw, _ = chunk[verdict["candidate"]]
            obj.position = Vec3(x, y, z)
            obj.rotation = Euler(0.0, 0.0, math.degrees(yaw))
            if verdict.get("resettled"):  # accepted at its settled pose: keep that pose
                px, py, pz, qw, qx, qy, qz = verdict["settled_pose"]
                obj.position = Vec3(px, py, pz)
                obj.rotation = _euler(qw, qx, qy, qz)
            return PlaceResult(
                True, obj.id, candidates=(k + 1) * batch, detail={"critic": "stable"}
            )
        failures.append(verdict)
    state.scene.objects.remove(obj)
    state.metas.pop(obj.id, None)
    last = failures[-1] if failures else {}
    return PlaceResult(
        False,
        None,
        f"no stable placement of {text!r} on {support_id}",
        candidates=len(cands),
        detail={"critic": {"summary": last.get("summary"), "suggestion": last.get("suggestion")}},
    )


def _storable(category: str) -> bool:
    """Whether objects of a category may be stored inside furniture (the catalogue's
    ``manipulable`` group: a mug in the cabinet, not the microwave)."""
    from factory.assets import CATEGORIES

    cat = CATEGORIES.get(category)
    return bool(cat is not None and cat.group == "manipulable")


def _fixed(category: str) -> bool:
    """The catalogue's ``fixed`` of a category (built-in furniture: static in simulation)."""
    from factory.assets import CATEGORIES

    cat = CATEGORIES.get(category)
    return bool(cat is not None and cat.fixed)
