"""Antipodal grasps from an object's collision geometry.

The object is the union of its convex collision pieces (as compiled: mesh hulls, boxes,
cylinders, spheres). A candidate starts from a point ``p`` sampled on the union's surface with
outward normal ``n``: one finger presses at ``p`` along the closing axis ``a = -n``; the other
finger meets the material where the line ``p + t a`` leaves the union (exact ray/half-space
intersection with every piece). The pair is antipodal when the exit normal lies inside the
friction cone around ``a``, and holdable when the span fits the open hand. Approach directions
are perpendicular to ``a``. Candidates are then filtered by collision of the open gripper (and
its pre-grasp pose) with the whole scene in the composed MuJoCo model, and ranked.

Frames: grasp poses are tool-site poses (see :mod:`factory.robots.panda`): +z approach, +x
closing axis; ``pose_tool_in_obj`` is a 4x4 transform in the object's body frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from factory.robots.panda import PANDA, RobotIndex, pose_matrix


@dataclass(frozen=True)
class GraspConfig:
    """Grasp sampling parameters.

    Attributes:
        samples: surface points sampled per object.
        approaches: approach directions tried per antipodal pair (around the closing axis).
        friction: friction coefficient of the cone test (finger pad on the object).
        width_margin: required slack between the span and the open hand (m).
        min_width: thinner spans are rejected (m).
        max_tilt_deg: approaches tilted more than this from straight down are dropped.
        pregrasp: retreat of the pre-grasp pose along the approach (m).
        clearance: required distance of the open gripper from everything (m).
        keep: candidates returned after filtering.
        pad_half: half size of the finger pad patch probed around each contact (m).
        min_contact: least share of the pad patch that must touch material on both sides.
    """

    samples: int = 600
    approaches: int = 8
    friction: float = 0.5
    width_margin: float = 0.012
    min_width: float = 0.003
    max_tilt_deg: float = 60.0
    pregrasp: float = 0.10
    clearance: float = 0.002
    keep: int = 24
    pad_half: float = 0.007
    min_contact: float = 0.6


@dataclass(frozen=True)
class Grasp:
    """One grasp.

    Attributes:
        pose_tool_in_obj: tool-site pose in the object frame (4, 4).
        width: span between the contacts (m).
        quality: antipodal quality in [0, 1] (cosine of the exit normal to the axis).
        contact: share of the finger-pad patch that meets material at the same span.
        score: ranking score (higher is better).
        contacts_in_obj: the two contact points (2, 3), object frame.
    """

    pose_tool_in_obj: np.ndarray
    width: float
    quality: float
    contact: float
    score: float
    contacts_in_obj: np.ndarray


@dataclass
class Piece:
    """A convex collision piece in the object frame: vertices, facets, outward half-spaces."""

    vertices: np.ndarray  # (v, 3)
    triangles: np.ndarray  # (f, 3) vertex indices
    normals: np.ndarray  # (f, 3) outward unit normals of the triangles
    planes: np.ndarray  # (h, 4): n . x + d <= 0 inside


def _primitive_vertices(gtype: int, size: np.ndarray) -> np.ndarray | None:
    g = mujoco.mjtGeom
    if gtype == g.mjGEOM_BOX:
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size
    if gtype in (g.mjGEOM_CYLINDER, g.mjGEOM_CAPSULE):
        ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        ring = np.stack([np.cos(ang), np.sin(ang)], 1) * size[0]
        half = size[1] + (size[0] if gtype == g.mjGEOM_CAPSULE else 0.0)
        return np.concatenate(
            [np.c_[ring, np.full(24, -half)], np.c_[ring, np.full(24, half)]], axis=0
        )
    if gtype == g.mjGEOM_SPHERE:
        phi = np.arccos(1 - 2 * (np.arange(60) + 0.5) / 60)
        th = np.pi * (1 + 5**0.5) * np.arange(60)
        return size[0] * np.c_[np.sin(phi) * np.cos(th), np.sin(phi) * np.sin(th), np.cos(phi)]
    if gtype == g.mjGEOM_ELLIPSOID:
        unit = _primitive_vertices(g.mjGEOM_SPHERE, np.ones(3))
        return None if unit is None else unit * size
    return None


def collision_pieces(model: mujoco.MjModel, body: int) -> list[Piece]:
    """The convex collision pieces of a body, in the body frame.

    Raises:
        ValueError: the body has no collision geometry.
    """
    pieces = []
    for gid in np.flatnonzero(model.geom_bodyid == body):
        if model.geom_contype[gid] == 0 and model.geom_conaffinity[gid] == 0:
            continue
        gtype = int(model.geom_type[gid])
        if gtype == mujoco.mjtGeom.mjGEOM_MESH:
            mid = int(model.geom_dataid[gid])
            adr, n = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
            verts = np.array(model.mesh_vert[adr : adr + n], dtype=float)
        else:
            prim = _primitive_vertices(gtype, np.array(model.geom_size[gid], dtype=float))
            if prim is None:
                continue
            verts = prim
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[gid])
        verts = verts @ rot.reshape(3, 3).T + model.geom_pos[gid]
        try:
            hull = ConvexHull(verts)
        except QhullError:
            continue
        tri = hull.simplices
        a, b, c = (verts[tri[:, k]] for k in range(3))
        nrm = np.cross(b - a, c - a)
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True) + 1e-12
        centre = verts[hull.vertices].mean(0)
        flip = np.einsum("ij,ij->i", nrm, a - centre) < 0
        nrm[flip] *= -1
        pieces.append(Piece(verts, tri, nrm, np.array(hull.equations)))
    if not pieces:
        raise ValueError(f"body {model.body(body).name!r} has no collision geometry")
    return pieces


def _line_intervals(
    pieces: list[Piece], origin: np.ndarray, axis: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Entry/exit parameters of lines ``origin + t axis`` through each piece.

    Args:
        origin, axis: (n, 3) each.

    Returns:
        ``t_in (n, P)``, ``t_out (n, P)`` (``t_in > t_out`` where the line misses) and the
        outward normal at each exit ``(n, P, 3)``.
    """
    n = len(origin)
    t_in = np.full((n, len(pieces)), -np.inf)
    t_out = np.full((n, len(pieces)), np.inf)
    exit_n = np.zeros((n, len(pieces), 3))
    for k, piece in enumerate(pieces):
        nrm, off = piece.planes[:, :3], piece.planes[:, 3]
        num = -(origin @ nrm.T + off)  # (n, h): n.x + d <= 0  <=>  t (n.a) <= num
        den = axis @ nrm.T
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / den
        enter = np.where(den < -1e-12, t, -np.inf)
        leave = np.where(den > 1e-12, t, np.inf)
        parallel_out = (np.abs(den) <= 1e-12) & (num < 0)
        t_in[:, k] = enter.max(1)
        t_out[:, k] = leave.min(1)
        t_in[parallel_out.any(1), k] = np.inf
        exit_n[:, k] = nrm[leave.argmin(1)]
    return t_in, t_out, exit_n


def _union_exit(
    t_in: np.ndarray, t_out: np.ndarray, start: float = 1e-4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where lines leave the union of pieces after entering at ``t ~ 0``.

    Each line's intervals are visited in order of entry (a stable sort, vectorised over the
    lines): consecutive overlapping intervals form one component of the union; the component
    holding ``start`` is the one the line is inside just after 0.

    Args:
        t_in, t_out: (n, P) entry/exit parameters per line and piece (``t_in >= t_out``: the
            line misses the piece).

    Returns:
        ``t_exit (n,)`` (NaN where the line is not inside the union just after 0), the piece
        index defining the exit ``(n,)``, and the start of the next material after the exit
        ``(n,)`` (inf if none).
    """
    n, pieces = t_in.shape
    valid = t_in < t_out
    order = np.argsort(np.where(valid, t_in, np.inf), axis=1, kind="stable")
    a_all = np.take_along_axis(t_in, order, 1)
    b_all = np.take_along_axis(t_out, order, 1)
    v_all = np.take_along_axis(valid, order, 1)
    comp_end = np.full(n, -np.inf)
    comp_arg = np.full(n, -1)
    found = np.zeros(n, bool)
    stopped = np.zeros(n, bool)
    nxt = np.full(n, np.inf)
    for j in range(pieces):
        a, b, k = a_all[:, j], b_all[:, j], order[:, j]
        active = v_all[:, j] & ~stopped
        new_comp = active & (a > comp_end + 1e-6)
        stop = new_comp & found  # the next material after the component holding ``start``
        nxt[stop] = a[stop]
        stopped |= stop
        begin = new_comp & ~found
        grow = active & ~new_comp & (b > comp_end)
        take = begin | grow
        comp_end = np.where(take, b, comp_end)
        comp_arg = np.where(take, k, comp_arg)
        found |= active & ~stop & (a <= start) & (start < comp_end)
    t_exit = np.where(found, comp_end, np.nan)
    which = np.where(found, comp_arg, 0)
    return t_exit, which, nxt


def _sample_surface(
    pieces: list[Piece], count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Points and outward normals on the union's surface (points inside other pieces dropped)."""
    tris, nrms, owner = [], [], []
    for k, piece in enumerate(pieces):
        tris.append(piece.vertices[piece.triangles])
        nrms.append(piece.normals)
        owner.append(np.full(len(piece.triangles), k))
    tri = np.concatenate(tris)
    nrm = np.concatenate(nrms)
    own = np.concatenate(owner)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    pick = rng.choice(len(tri), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    w = np.stack([1 - s, s * (1 - r2), s * r2], 1)
    pts = np.einsum("nk,nkj->nj", w, tri[pick])
    keep = np.ones(count, bool)
    for k, piece in enumerate(pieces):
        inside = (pts @ piece.planes[:, :3].T + piece.planes[:, 3] < -1e-4).all(1)
        keep &= ~(inside & (own[pick] != k))
    return pts[keep], nrm[pick][keep]


def pad_contacts(
    pieces: list[Piece],
    points: np.ndarray,
    axes: np.ndarray,
    approaches: np.ndarray,
    widths: np.ndarray,
    half: float,
    tol: float = 0.003,
) -> np.ndarray:
    """Share of a finger-pad patch around each contact that grips material at the same span.

    Lines parallel to the closing axis through a 3x3 patch (``half`` m around the contact in
    the plane of the approach and ``axis x approach``) must enter the object within ``tol`` of
    the contact plane and leave it within ``tol`` of the other finger.

    Args:
        pieces: the object's convex pieces (object frame).
        points: (n, 3) contacts of the first finger (object frame, m).
        axes: (n, 3) closing axes (unit).
        approaches: (n, 3) approach directions (unit, perpendicular to the axes).
        widths: (n,) spans between the fingers' contacts (m).
        half: half size of the patch (m).
        tol: allowed mismatch (m).

    Returns:
        (n,) shares in [0, 1].
    """
    points, axes = np.asarray(points, float), np.asarray(axes, float)
    approaches, widths = np.asarray(approaches, float), np.asarray(widths, float)
    n = len(points)
    if n == 0:
        return np.zeros(0)
    side = np.cross(axes, approaches)
    offs = np.array([(u, v) for u in (-half, 0.0, half) for v in (-half, 0.0, half)])  # (9, 2)
    origin = (
        points[:, None]
        + offs[None, :, :1] * approaches[:, None]
        + offs[None, :, 1:] * side[:, None]
        - axes[:, None] * 0.01
    ).reshape(-1, 3)
    axis = np.repeat(axes, len(offs), axis=0)
    t_in, t_out, _ = _line_intervals(pieces, origin, axis)
    t_exit, _, _ = _union_exit(t_in - 0.01, t_out - 0.01, start=tol)
    hits = t_in < t_out
    first = np.where(hits, t_in - 0.01, np.inf).min(1)
    width = np.repeat(widths, len(offs))
    good = (np.abs(first) <= tol) & (np.abs(t_exit - width) <= tol)
    return np.asarray(good.reshape(n, len(offs)).mean(1))


@dataclass
class _Pairs:
    """Antipodal pairs of surface samples and every approach around each (object frame).

    Attributes:
        sample: (m,) index of each pair's surface sample.
        pts: (m, 3) the first finger's contact point.
        axis: (m, 3) closing axis.
        width: (m,) span (m).
        quality: (m,) exit normal along the axis (cosine).
        dirs: (m, A, 3) approach directions (unit, perpendicular to the axis).
    """

    sample: np.ndarray
    pts: np.ndarray
    axis: np.ndarray
    width: np.ndarray
    quality: np.ndarray
    dirs: np.ndarray


def _antipodal_pairs(
    pieces: list[Piece], pts: np.ndarray, nrm: np.ndarray, cfg: GraspConfig
) -> _Pairs:
    """The antipodal, holdable pairs among surface samples ``pts`` (k, 3) with normals ``nrm``."""
    axis = -nrm
    t_in, t_out, exit_n = _line_intervals(pieces, pts, axis)
    t_exit, which, nxt = _union_exit(t_in, t_out)
    open_w = 2 * PANDA.finger_max
    ok = np.isfinite(t_exit) & (t_exit >= cfg.min_width) & (t_exit <= open_w - cfg.width_margin)
    # The far finger must not meet more material on its way in (e.g. a handle behind a wall).
    ok &= ~(nxt < t_exit / 2 + open_w / 2 + 0.01)
    idx = np.flatnonzero(ok)
    n_exit = exit_n[idx, which[idx]]
    quality = np.einsum("ij,ij->i", n_exit, axis[idx])
    cone = 1 / np.sqrt(1 + cfg.friction**2)
    good = quality >= cone
    idx, quality = idx[good], quality[good]
    a = axis[idx]  # (m, 3)
    helper = np.where(
        (np.abs(a[:, 2]) < 0.9)[:, None], np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    )
    u = np.cross(a, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(a, u)
    th = np.linspace(0, 2 * np.pi, cfg.approaches, endpoint=False)
    dirs = np.cos(th)[None, :, None] * u[:, None] + np.sin(th)[None, :, None] * v[:, None]
    return _Pairs(idx, pts[idx], a, t_exit[idx], quality, dirs.reshape(len(idx), len(th), 3))


def _ranked(
    pairs: _Pairs,
    pair: np.ndarray,
    d: np.ndarray,
    down: np.ndarray,
    contact: np.ndarray,
    com_in_obj: np.ndarray | None,
) -> list[Grasp]:
    """Grasps of (pair index, approach ``d``) candidates, scored, best per cell, best first."""
    open_w = 2 * PANDA.finger_max
    a, width = pairs.axis, pairs.width
    centre = pairs.pts + a * width[:, None] / 2
    com = np.zeros(3) if com_in_obj is None else np.asarray(com_in_obj)
    off = np.linalg.norm(np.cross(centre[pair] - com, d), axis=1)
    q = pairs.quality[pair]
    score = 0.5 * q + 0.35 * down + 0.4 * contact - 0.8 * off + 0.15 * (1 - width[pair] / open_w)
    # Many samples give nearly the same approach: keep the best per (centre, approach) cell.
    order = np.argsort(-score, kind="stable")
    keys = np.concatenate(
        [np.round(centre[pair] / 0.01).astype(int), np.round(d * 4).astype(int)], axis=1
    )
    _, first = np.unique(keys[order], axis=0, return_index=True)
    out: list[Grasp] = []
    for j in order[np.sort(first)]:
        p = pair[j]
        ai, dj = a[p], d[j]
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = ai, np.cross(dj, ai), dj, centre[p]
        out.append(
            Grasp(
                pose,
                float(width[p]),
                float(q[j]),
                float(contact[j]),
                float(score[j]),
                np.stack([pairs.pts[p], pairs.pts[p] + ai * width[p]]),
            )
        )
    return out


def _down_obj(rot_obj_in_world: np.ndarray) -> np.ndarray:
    return np.asarray(rot_obj_in_world).T @ np.array([0.0, 0.0, -1.0])


def antipodal_candidates(
    pieces: list[Piece],
    rot_obj_in_world: np.ndarray,
    cfg: GraspConfig,
    rng: np.random.Generator,
    com_in_obj: np.ndarray | None = None,
) -> list[Grasp]:
    """Antipodal grasp candidates of an object, geometry only (no scene collision yet).

    Args:
        pieces: the object's convex pieces (:func:`collision_pieces`), object frame.
        rot_obj_in_world: the object's orientation (3, 3), to prefer top-down approaches.
        cfg: sampling parameters.
        rng: random generator.
        com_in_obj: centre of mass (3,), object frame; spans near it rank higher.

    Returns:
        candidates sorted by score (best first).
    """
    pts, nrm = _sample_surface(pieces, cfg.samples, rng)
    pairs = _antipodal_pairs(pieces, pts, nrm, cfg)
    pair = np.repeat(np.arange(len(pairs.sample)), cfg.approaches)
    d = pairs.dirs.reshape(-1, 3)
    down = d @ _down_obj(rot_obj_in_world)
    keep = down >= np.cos(np.radians(cfg.max_tilt_deg))
    pair, d, down = pair[keep], d[keep], down[keep]
    contact = pad_contacts(
        pieces, pairs.pts[pair], pairs.axis[pair], d, pairs.width[pair], cfg.pad_half
    )
    keep = contact >= cfg.min_contact
    return _ranked(pairs, pair[keep], d[keep], down[keep], contact[keep], com_in_obj)


class GraspPool:
    """The antipodal pairs of one object, computed once, from which each episode draws.

    :func:`antipodal_candidates` samples the surface, intersects lines and probes the finger
    pads anew for every episode, about half of an episode's planning time, although the object's
    shape never changes between the episodes of a scene. A pool samples ``factor`` times the
    samples once and intersects their lines; an episode then draws ``cfg.samples`` of those
    samples with its own generator and keeps their pairs: the same kind of candidates, as
    random per episode. The finger pads of a (pair, approach) are probed the first time an
    episode needs them and kept.

    Args:
        pieces: the object's convex pieces, object frame.
        cfg: sampling parameters.
        seed: the pool's samples (deterministic per seed).
        com_in_obj: centre of mass (3,), object frame.
        factor: samples in the pool per ``cfg.samples``.
    """

    def __init__(
        self,
        pieces: list[Piece],
        cfg: GraspConfig,
        seed: int,
        com_in_obj: np.ndarray | None = None,
        factor: int = 4,
    ) -> None:
        self.cfg = cfg
        self.com = com_in_obj
        self.size = cfg.samples * factor
        pts, nrm = _sample_surface(pieces, self.size, np.random.default_rng(seed))
        self.size = len(pts)
        self.pairs = _antipodal_pairs(pieces, pts, nrm, cfg)
        m, na = len(self.pairs.sample), cfg.approaches
        self._pair = np.repeat(np.arange(m), na)
        self._d = self.pairs.dirs.reshape(-1, 3)
        self._pieces = pieces
        # Pad contacts are probed when an episode first needs them (NaN: not yet).
        self._contact = np.full(len(self._pair), np.nan)

    def candidates(self, rot_obj_in_world: np.ndarray, rng: np.random.Generator) -> list[Grasp]:
        """Candidates of one episode (as :func:`antipodal_candidates`), best first.

        Args:
            rot_obj_in_world: the object's orientation (3, 3).
            rng: the episode's generator (draws which pool samples take part).
        """
        cfg = self.cfg
        drawn = np.zeros(self.size, bool)
        drawn[rng.choice(self.size, min(cfg.samples, self.size), replace=False)] = True
        down = self._d @ _down_obj(rot_obj_in_world)
        keep = drawn[self.pairs.sample[self._pair]] & (down >= np.cos(np.radians(cfg.max_tilt_deg)))
        need = np.flatnonzero(keep & np.isnan(self._contact))
        if len(need):
            p, pair = self.pairs, self._pair[need]
            self._contact[need] = pad_contacts(
                self._pieces, p.pts[pair], p.axis[pair], self._d[need], p.width[pair], cfg.pad_half
            )
        keep &= self._contact >= cfg.min_contact
        return _ranked(
            self.pairs, self._pair[keep], self._d[keep], down[keep], self._contact[keep], self.com
        )


def facing_order(
    grasps: list[Grasp],
    pose_obj_in_world: np.ndarray,
    base_xy_in_world: np.ndarray,
    weight: float,
) -> list[Grasp]:
    """Grasps made consistent for learning: on the side facing the robot, one hand orientation.

    A policy trained on the demos sees the object, not the planner's random draw of its
    surface points; if the grasp lands anywhere around a mug's rim, the demos teach every
    azimuth at once and an imitation policy averages them into the middle of the mug. So the
    candidates are ranked by ``score + weight * cos(azimuth)``, where the azimuth is the angle,
    seen from above, between the grasp centre's offset from the object and the direction from
    the object to the robot base (0: the side facing the robot), and the parallel gripper's
    two symmetric ways of holding the same grasp (rotated by 180 degrees about the approach)
    are reduced to the one whose closing axis points away from the robot.

    Args:
        grasps: candidates (object frame), e.g. :func:`antipodal_candidates`.
        pose_obj_in_world: the object's pose (4, 4).
        base_xy_in_world: the robot base position (2,), world frame (m).
        weight: strength of the facing preference; 0 keeps the geometric ranking and the
            sampled hand orientations.

    Returns:
        the candidates, re-oriented and re-ranked (best first).
    """
    if weight <= 0:
        return list(grasps)
    obj_xy = pose_obj_in_world[:2, 3]
    toward = np.asarray(base_xy_in_world, float) - obj_xy
    toward /= max(float(np.linalg.norm(toward)), 1e-9)
    flip = np.diag([-1.0, -1.0, 1.0, 1.0])  # 180 degrees about the tool's approach axis
    ranked = []
    for g in grasps:
        pose = g.pose_tool_in_obj
        world = pose_obj_in_world @ pose
        if float(world[:2, 0] @ toward) > 0:  # closing axis points at the robot: flip it
            pose = pose @ flip
        off = world[:2, 3] - obj_xy
        norm = float(np.linalg.norm(off))
        facing = float(off @ toward) / norm if norm > 1e-4 else 0.0
        ranked.append((g.score + weight * facing, replace(g, pose_tool_in_obj=pose)))
    ranked.sort(key=lambda t: -t[0])
    return [g for _, g in ranked]


@dataclass
class GripperShape:
    """The collision geoms of the open gripper, relative to the tool site.

    Attributes:
        geoms: geom ids in the composed model (n,).
        pose_geom_in_tool: (n, 4, 4).
    """

    geoms: np.ndarray
    pose_geom_in_tool: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel, robot: RobotIndex, opening: float) -> GripperShape:
        data = mujoco.MjData(model)
        data.qpos[robot.finger_qpos] = robot.finger_pos(opening)
        mujoco.mj_kinematics(model, data)
        site = pose_matrix(data.site_xpos[robot.site], data.site_xmat[robot.site])
        inv = np.linalg.inv(site)
        geoms = robot.finger_geoms
        rel = np.stack([inv @ pose_matrix(data.geom_xpos[g], data.geom_xmat[g]) for g in geoms])
        return cls(geoms, rel)


def gripper_clear(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    shape: GripperShape,
    pose_tool_in_world: np.ndarray,
    clearance: float,
    ignore_bodies: np.ndarray,
) -> bool:
    """Whether the open gripper at a tool pose stays ``clearance`` away from every scene geom.

    ``data`` must hold the scene's kinematics (``mj_kinematics``); the gripper geoms' poses in
    it are overwritten.
    """
    for g, rel in zip(shape.geoms, shape.pose_geom_in_tool, strict=True):
        pose = pose_tool_in_world @ rel
        data.geom_xpos[g] = pose[:3, 3]
        data.geom_xmat[g] = pose[:3, :3].reshape(-1)
    centre = pose_tool_in_world[:3, 3]
    near = np.linalg.norm(data.geom_xpos - centre, axis=1) < model.geom_rbound + 0.2
    collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    others = np.flatnonzero(near & collides & ~np.isin(model.geom_bodyid, ignore_bodies))
    for g in shape.geoms:
        for o in others:
            if mujoco.mj_geomDistance(model, data, int(g), int(o), clearance, None) < clearance:
                return False
    return True
