"""Scene metrics: object count, collision ratio (two tests), stability ratio, per room type.

* Collision, MuJoCo: an object collides if it interpenetrates another *object* (not the floor
  or a wall) by more than ``tol`` (1 cm) at rest, from MuJoCo's contacts.
* Collision, trimesh (the paper's test): rays cast along every edge of an object's collision
  mesh against the other objects' meshes; an edge that enters another mesh means the two
  intersect; a mesh with a vertex inside another (wholly contained, which no edge reveals)
  intersects it too. Meshes are first shrunk by ``tol`` towards their centre so that resting contact
  (touching faces) does not count, as in the MuJoCo test.
* Stability: the fraction of free objects stable under the protocol of
  :mod:`factory.sim.stability`.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from factory.schema import Scene
from factory.sim.stability import StabilityResult, body_penetration


@dataclass(frozen=True)
class ObjectMeshes:
    """World-frame collision meshes of the scene's objects (trimesh), by object id."""

    meshes: dict[str, Any]

    @classmethod
    def of(cls, model: mujoco.MjModel, data: mujoco.MjData, object_ids: list[str]) -> ObjectMeshes:
        import trimesh

        out: dict[str, Any] = {}
        for oid in object_ids:
            bid = model.body(oid).id
            parts = []
            for g in range(
                model.body_geomadr[bid], model.body_geomadr[bid] + model.body_geomnum[bid]
            ):
                if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
                    continue
                tf = np.eye(4)
                tf[:3, :3] = data.geom_xmat[g].reshape(3, 3)
                tf[:3, 3] = data.geom_xpos[g]
                gtype = model.geom_type[g]
                if gtype == mujoco.mjtGeom.mjGEOM_BOX:
                    part = trimesh.creation.box(extents=2 * model.geom_size[g])
                elif gtype == mujoco.mjtGeom.mjGEOM_MESH:
                    mid = model.geom_dataid[g]
                    v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
                    f0, nf = model.mesh_faceadr[mid], model.mesh_facenum[mid]
                    part = trimesh.Trimesh(
                        model.mesh_vert[v0 : v0 + nv], model.mesh_face[f0 : f0 + nf], process=False
                    ).convex_hull
                else:
                    continue
                part.apply_transform(tf)
                parts.append(part)
            if parts:
                out[oid] = trimesh.util.concatenate(parts) if len(parts) > 1 else parts[0]
        return cls(out)


def _shrunk(mesh: Any, tol: float) -> Any:
    ext = mesh.extents
    scale = np.clip((ext - 2 * tol) / np.maximum(ext, 1e-9), 0.05, 1.0)
    c = mesh.bounds.mean(axis=0)
    m = mesh.copy()
    m.vertices = c + (m.vertices - c) * scale
    return m


def trimesh_collisions(meshes: ObjectMeshes, tol: float = 0.01) -> list[tuple[str, str]]:
    """Pairs of objects whose (shrunk) meshes intersect, by ray casts along mesh edges."""
    ids = sorted(meshes.meshes)
    shrunk = {oid: _shrunk(meshes.meshes[oid], tol) for oid in ids}
    bounds = {oid: shrunk[oid].bounds for oid in ids}
    pairs = []
    for a_i, a in enumerate(ids):
        for b in ids[a_i + 1 :]:
            ba, bb = bounds[a], bounds[b]
            if np.any(ba[1] < bb[0]) or np.any(bb[1] < ba[0]):
                continue
            if _edges_hit(shrunk[a], shrunk[b]) or _edges_hit(shrunk[b], shrunk[a]):
                pairs.append((a, b))
    return pairs


def _edges_hit(src: Any, target: Any) -> bool:
    """Whether an edge of ``src`` enters ``target``, or ``src`` lies inside it."""
    if target.is_watertight and bool(np.any(target.contains(src.vertices))):
        return True
    edges = src.edges_unique
    v = src.vertices
    origins = v[edges[:, 0]]
    vec = v[edges[:, 1]] - origins
    length = np.linalg.norm(vec, axis=1)
    keep = length > 1e-9
    if not keep.any():
        return False
    origins, vec, length = origins[keep], vec[keep], length[keep]
    dirs = vec / length[:, None]
    locs, ray_idx, _ = target.ray.intersects_location(origins, dirs, multiple_hits=False)
    if len(ray_idx) == 0:
        return False
    dist = np.linalg.norm(locs - origins[ray_idx], axis=1)
    return bool(np.any(dist < length[ray_idx] - 1e-9))


def scene_metrics(
    scene: Scene,
    model: mujoco.MjModel,
    result: StabilityResult,
    tol: float = 0.01,
    trimesh_test: bool = True,
) -> dict[str, Any]:
    """Metrics of one scene at its given state (candidate 0 of ``result``).

    Returns:
        a JSON-ready dict: ``objects``, ``collision`` (MuJoCo and trimesh), ``stability``,
        per-object verdicts and per room type counts.
    """
    ids = [o.id for o in scene.objects]
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bodies = np.array([model.body(i).id for i in ids], dtype=int)
    depth, pairs = body_penetration(model, data.qpos[None, :].copy(), bodies, set(bodies.tolist()))
    colliding = {oid: pairs[0][j] for j, oid in enumerate(ids) if depth[0, j] > tol}
    tri_pairs = trimesh_collisions(ObjectMeshes.of(model, data, ids), tol) if trimesh_test else []
    tri_objects = sorted({o for p in tri_pairs for o in p})
    free = {oid: j for j, oid in enumerate(result.object_ids)}
    links: dict[str, list[int]] = defaultdict(list)  # object id -> its links' columns
    for j, name in enumerate(result.object_ids):
        owner, sep, _ = name.partition("/")  # a link's body is "<object id>/<link>"
        if sep:
            links[owner].append(j)
    per_object: dict[str, Any] = {}
    for j, obj in enumerate(scene.objects):
        entry: dict[str, Any] = {
            "room_id": obj.room_id,
            "static": obj.is_static,
            "penetration_m": float(depth[0, j]),
            "colliding": obj.id in colliding,
        }
        k = free.get(obj.id)
        if k is not None:
            entry.update(
                translation_m=float(result.translation[0, k]),
                rotation_deg=float(result.rotation_deg[0, k]),
                stable=bool(result.stable_object[0, k]) and not bool(result.invalid[0]),
            )
        else:
            entry["stable"] = True  # static objects do not move
        if links.get(obj.id):  # its doors and drawers stay where they are
            held = {
                result.object_ids[k]: {
                    "translation_m": float(result.translation[0, k]),
                    "rotation_deg": float(result.rotation_deg[0, k]),
                    "stable": bool(result.stable_object[0, k]) and not bool(result.invalid[0]),
                }
                for k in links[obj.id]
            }
            entry["links"] = held
            entry["stable"] = entry["stable"] and all(v["stable"] for v in held.values())
        per_object[obj.id] = entry
    n = len(ids)
    rooms = {r.id: r.room_type for r in scene.rooms}
    per_room: dict[str, dict[str, int]] = defaultdict(
        lambda: {"objects": 0, "colliding": 0, "stable": 0}
    )
    for e in per_object.values():
        r = per_room[rooms[e["room_id"]]]
        r["objects"] += 1
        r["colliding"] += int(e["colliding"])
        r["stable"] += int(e["stable"])
    n_stable = sum(int(e["stable"]) for e in per_object.values())
    return {
        "objects": n,
        "dynamic_objects": len([o for o in result.object_ids if "/" not in o]),
        "collision": {
            "ratio": len(colliding) / n if n else 0.0,
            "colliding": sorted(colliding),
            "pairs": sorted(colliding.values()),
            "tolerance_m": tol,
        },
        "collision_trimesh": {
            "ratio": len(tri_objects) / n if n else 0.0,
            "colliding": tri_objects,
            "pairs": [list(p) for p in tri_pairs],
        }
        if trimesh_test
        else None,
        "stability": {
            "ratio": n_stable / n if n else 1.0,
            "unstable": sorted(o for o, e in per_object.items() if not e["stable"]),
            "invalid": bool(result.invalid[0]),
            "reason": result.reasons[0],
        },
        "per_room_type": dict(per_room),
        "per_object": per_object,
    }


def measure_scene(
    scene: Scene,
    assets_root: Any = None,
    backend: Any = "cpu",
    tol: float = 0.01,
    trimesh_test: bool = True,
) -> dict[str, Any]:
    """Compiles a scene, settles it under the strict protocol (no resettling; initial
    interpenetration is measured as collision, not treated as invalid) and measures it.

    Returns:
        :func:`scene_metrics` of the scene.
    """
    import math

    from factory.sim.compile import compile_scene
    from factory.sim.stability import StabilityProtocol, check_stability

    model = compile_scene(scene, assets_root).model
    protocol = StabilityProtocol(penetration_tol=math.inf, resettle=False)
    result = check_stability(model, backend=backend, protocol=protocol)
    return scene_metrics(scene, model, result, tol=tol, trimesh_test=trimesh_test)
