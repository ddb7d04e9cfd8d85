"""The generator tools and critics as one session: JSON in, JSON out, never an exception.

A :class:`ToolSession` holds one scene under construction. Its public methods are the tools
the agent calls (directly, or over MCP through :mod:`.mcp_server`); each returns a
JSON-serialisable dict, with ``{"ok": false, "error": ...}`` for a bad call.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from factory.assets import AssetLibrary
from factory.cores import usable_cores
from factory.errors import ConfigError, FactoryError
from factory.scenes.critics import visual_critic
from factory.scenes.placement import SceneState, place_floor, place_on, place_wall
from factory.schema import Scene, to_dict, validate
from factory.sim.critic import SCOPES, physics_critic
from factory.sim.stability import StabilityProtocol

log = logging.getLogger(__name__)

TOOLS: tuple[str, ...] = (
    "init_scene",
    "place_objects",
    "move_object",
    "remove_object",
    "get_scene_info",
    "render_views",
    "visual_critic",
    "physics_critic",
    "route_critic",
    "get_scene_json",
)


def _carry(scene: Scene, root: str, old: Any, new: Any) -> None:
    """Moves everything standing (directly or not) on ``root`` from its old pose to its new."""
    import math as _m

    y0, y1 = _m.radians(old.rotation.z), _m.radians(new.rotation.z)
    c0, s0, c1, s1 = _m.cos(y0), _m.sin(y0), _m.cos(y1), _m.sin(y1)
    dz = new.position.z - old.position.z
    carried = scene.with_dependents({root}) - {root}
    for o in scene.objects:
        if o.id in carried:
            dx, dy = o.position.x - old.position.x, o.position.y - old.position.y
            lx, ly = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
            o.position.x = new.position.x + c1 * lx - s1 * ly
            o.position.y = new.position.y + s1 * lx + c1 * ly
            o.position.z += dz
            o.rotation.z += _m.degrees(y1 - y0)


def _safe(fn: Callable[..., dict[str, Any]]) -> Callable[..., dict[str, Any]]:
    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> dict[str, Any]:
        try:
            return fn(*args, **kwargs)
        except (FactoryError, ValueError, KeyError, TypeError) as e:
            msg = str(e) if not isinstance(e, KeyError) else f"unknown id {e}"
            return {"ok": False, "error": f"{fn.__name__}: {msg}"}

    return wrapper


class ToolSession:
    """One scene and the tools that edit it.

    Args:
        library: the asset library.
        physics: run the physics critic inside every on-top placement (the paper's loop).
        out_dir: where ``render_views`` writes images.
        critic_scope: what the placement critic simulates: ``local`` (the candidate and what
            it can touch, :mod:`factory.sim.local_critic`; the same verdicts, a cost that does
            not grow with the scene) or ``scene`` (the whole scene per candidate).
        critic_chunk: candidates simulated at a time, in order, stopping at the first chunk
            with a good one (default: one per CPU core, the CPU backend's threads).
    """

    def __init__(
        self,
        library: AssetLibrary,
        physics: bool = True,
        out_dir: str | Path | None = None,
        critic_scope: str = "local",
        critic_chunk: int | None = None,
    ) -> None:
        self.library = library
        self.physics = physics
        self.out_dir = Path(out_dir) if out_dir else None
        if critic_scope not in SCOPES:
            raise ConfigError(f"critic scope {critic_scope!r} must be one of {', '.join(SCOPES)}")
        self.critic_scope = critic_scope
        self.critic_chunk = critic_chunk or usable_cores()
        self.state: SceneState | None = None

    # ---- helpers
    def _require(self) -> SceneState:
        if self.state is None:
            raise ValueError("no scene yet: call init_scene first")
        return self.state

    def _critic(self) -> Callable[..., dict[str, Any]] | None:
        if not self.physics:
            return None

        def critic(scene: Scene, oid: str, poses: list[list[float]]) -> dict[str, Any]:
            return physics_critic(
                scene,
                oid,
                poses,
                assets_root=self.library.assets_dir,
                protocol=StabilityProtocol(resettle=True),
                scope=self.critic_scope,
                chunk=self.critic_chunk,
            )

        return critic

    @property
    def scene(self) -> Scene:
        return self._require().scene

    # ---- tools
    @_safe
    def init_scene(self, request: str, seed: int = 0) -> dict[str, Any]:
        """Creates an empty room for the request (type, size, materials, door, window)."""
        from factory.scenes.floorplan import init_scene

        if not request or not request.strip():
            raise ValueError("the request is empty: describe the scene")
        scene, info = init_scene(request, seed)
        self.state = SceneState(scene, self.library, seed)
        room = scene.rooms[0]
        return {
            "ok": True,
            "scene_id": scene.id,
            "room_id": room.id,
            **info,
            "walls": [w.id for w in room.walls],
        }

    @_safe
    def place_objects(
        self,
        text: str,
        placement: str | None = None,
        rule: str = "wall",
        target: str | None = None,
        height: float = 1.3,
        count: int = 1,
        task_role: str | None = None,
        room_id: str | None = None,
    ) -> dict[str, Any]:
        """Places ``count`` objects described by ``text``.

        ``placement`` is ``floor`` (``rule``: wall, corner, free, center, near, around,
        facing, away; ``target`` for the last four), ``wall`` (mounted at ``height`` m) or
        ``on_top`` (on a support surface of ``target``: tops, shelf boards, seats, inside
        vessels) or ``inside`` (stored behind a door or in a drawer of ``target``, an
        articulated object). ``room_id`` picks the room (default: the first) for floor and wall
        placement. With no ``placement``, the text may carry its constraint: "a lamp on the
        nightstand", "a tv stand facing the sofa", "a plant in the corner", "a painting on
        the wall".
        """
        state = self._require()
        if placement is None:
            from factory.scenes.constraints import parse_constraint

            c = parse_constraint(text, state.scene)
            if c.target_text and c.target is None:
                raise ValueError(f"no {c.target_text!r} in the scene to place {c.text!r} by")
            text, placement = c.text, c.placement
            rule, target = (c.rule, c.target) if c.placement != "on_top" else (rule, c.target)
        if placement not in ("floor", "wall", "on_top", "inside"):
            raise ValueError(f"placement {placement!r} must be floor, wall, on_top or inside")
        if not 1 <= count <= 20:
            raise ValueError("count must be 1..20")
        if placement in ("on_top", "inside") and not target:
            raise ValueError(f"{placement} placement needs target=<object id>")
        if target is not None:
            state.scene.object(target)  # KeyError -> clear error
        if room_id is not None:
            state.scene.room(room_id)
        placed: list[dict[str, Any]] = []
        failures: list[dict[str, Any]] = []
        for _ in range(count):
            if placement == "floor":
                res = place_floor(
                    state, text, rule, room_id=room_id, target=target, task_role=task_role
                )
            elif placement == "wall":
                res = place_wall(state, text, height, room_id=room_id)
            else:
                res = place_on(
                    state,
                    text,
                    str(target),
                    self._critic(),
                    task_role=task_role,
                    inside=placement == "inside",
                )
            (placed if res.ok else failures).append(res.as_dict())
        return {
            "ok": bool(placed),
            "placed": [p["object_id"] for p in placed],
            "failures": failures,
            "objects": len(state.scene.objects),
        }

    @_safe
    def move_object(
        self,
        object_id: str,
        placement: str = "floor",
        rule: str = "free",
        target: str | None = None,
        room_id: str | None = None,
    ) -> dict[str, Any]:
        """Moves an object (the same asset, id and task role) elsewhere with the placement
        logic (``room_id`` picks the room of a floor placement, default the first); what
        stands on it moves along; restores everything on failure."""
        state = self._require()
        obj = state.scene.object(object_id)
        if room_id is not None:
            state.scene.room(room_id)
        meta = state.metas.get(object_id)
        index = state.scene.objects.index(obj)
        state.scene.objects.remove(obj)
        text = obj.description or obj.category.replace("_", " ")
        state.reuse = state.meta_of(obj) if meta is None else (meta, state.meta_of(obj)[1])
        role = obj.task_role
        if placement == "on_top" and target:
            res = place_on(state, text, target, self._critic(), task_role=role)
        elif placement == "wall":
            res = place_wall(state, text, obj.position.z)
        else:
            res = place_floor(state, text, rule, room_id=room_id, target=target, task_role=role)
        state.reuse = None
        if not res.ok:
            state.scene.objects.insert(index, obj)
            if meta is not None:
                state.metas[object_id] = meta
            return {"ok": False, "error": f"move_object: {res.reason}; {object_id} stays put"}
        new = state.scene.object(res.object_id)  # type: ignore[arg-type]
        new.id = object_id  # keep the id
        state.metas[object_id] = state.metas.pop(res.object_id, meta)  # type: ignore[arg-type]
        _carry(state.scene, object_id, obj, new)
        return {
            "ok": True,
            "object_id": object_id,
            "position": [new.position.x, new.position.y, new.position.z],
        }

    @_safe
    def remove_object(self, object_id: str) -> dict[str, Any]:
        """Removes an object and whatever stands on it."""
        state = self._require()
        state.scene.object(object_id)
        gone = state.scene.with_dependents({object_id})
        state.scene.objects = [o for o in state.scene.objects if o.id not in gone]
        return {"ok": True, "removed": sorted(gone), "objects": len(state.scene.objects)}

    @_safe
    def get_scene_info(self) -> dict[str, Any]:
        """Rooms and objects (id, category, placement, position, size) of the scene."""
        scene = self.scene
        return {
            "ok": True,
            "scene_id": scene.id,
            "rooms": [
                {
                    "id": r.id,
                    "room_type": r.room_type,
                    "size_m": [r.dimensions.width, r.dimensions.length],
                }
                for r in scene.rooms
            ],
            "objects": [
                {
                    "id": o.id,
                    "category": o.category,
                    "room_id": o.room_id,
                    "placement": o.placement.kind,
                    "support": o.placement.support_id,
                    "task_role": o.task_role,
                    "position": [
                        round(o.position.x, 3),
                        round(o.position.y, 3),
                        round(o.position.z, 3),
                    ],
                    "size": [round(v, 3) for v in o.dimensions.as_tuple()],
                }
                for o in scene.objects
            ],
        }

    @_safe
    def render_views(self, width: int = 320, height: int = 240) -> dict[str, Any]:
        """Renders the five views; returns the PNG paths."""
        if self.out_dir is None:
            raise ValueError("this session has no output folder for renders")
        from factory.scenes.render import VIEWS, png_bytes, render_views
        from factory.sim.compile import compile_scene
        from factory.store import atomic_write_bytes

        model = compile_scene(self.scene, self.library.assets_dir).model
        images = render_views(model, self.scene, VIEWS, width, height)
        paths = {}
        for view, image in images.items():
            path = self.out_dir / f"{self.scene.id}_{view}.png"
            atomic_write_bytes(path, png_bytes(image))
            paths[view] = str(path)
        return {"ok": True, "images": paths}

    @_safe
    def visual_critic(self) -> dict[str, Any]:
        """Rule-based suggestions: missing task objects, companions, sparse areas, blocked
        doors, objects outside rooms."""
        return {"ok": True, **visual_critic(self._require())}

    @_safe
    def physics_critic(self) -> dict[str, Any]:
        """Collision and stability metrics of the whole scene as it stands."""
        from factory.sim.metrics import measure_scene

        m = measure_scene(self.scene, self.library.assets_dir, trimesh_test=False)
        return {
            "ok": True,
            "objects": m["objects"],
            "collision_ratio": m["collision"]["ratio"],
            "colliding": m["collision"]["colliding"],
            "stability_ratio": m["stability"]["ratio"],
            "unstable": m["stability"]["unstable"],
        }

    @_safe
    def route_critic(self, clear: bool = False) -> dict[str, Any]:
        """The mobile task's route: whether the robot's base can stand within reach of the
        object to pick and of the place support (at least 1.5 m apart; ``gap``: between their
        edges) and drive between them
        (``reason`` "" when it can, else no_route, no_pick_pose, no_place_pose, no_spawn_area,
        no_place_support, place_support_too_close, place_support_too_small; ``applies`` is
        false for a scene without a mobile task). With ``clear``, ``clear`` names the light
        floor objects whose removal would open a blocked route."""
        from factory.nav.route import check_route, is_mobile_task

        scene = self.scene
        if not is_mobile_task(scene):
            return {"ok": True, "applies": False, "reason": ""}
        verdict = check_route(scene, self.library.assets_dir, suggest_clear=clear)
        return {"ok": True, "applies": True, **verdict.as_dict()}

    @_safe
    def get_scene_json(self) -> dict[str, Any]:
        """The validated scene as scene.json content."""
        scene = validate(self.scene)
        return {"ok": True, "scene": to_dict(scene)}
