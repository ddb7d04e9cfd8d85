"""The heuristic brain's steps: its knobs, its state and the tool calls of each step.

:class:`Brain` holds the steps of the paper's loop over any tool caller (a
:class:`~.tools.ToolSession`, or an MCP client): furnish the rooms, drop unstable furniture,
place the task's objects, put small objects on surfaces with the physics critic judging each,
then the visual critic's suggestions and fillers, and for a mobile task a last route check
(:meth:`Brain.keep_route`). :func:`~.brain.heuristic_agent` runs them on one scene;
:mod:`.per_room` runs them room by room.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.scenes.part_read import (
    PartSpec,
    catalogue_category,
    check_part_request,
    openable_category,
)
from factory.scenes.request import TaskSpec, parse_request, request_task
from factory.scenes.rooms import ROOM_TYPES, Item

log = logging.getLogger(__name__)

MAX_MADE_ROOM = 2
"""Most light floor objects :meth:`Brain.make_room` takes out to put the mobile task's place
support far enough from the pick's support."""


@dataclass
class AgentConfig:
    """Knobs of the heuristic agent."""

    physics_critic: bool = True
    max_objects: int = 120
    """Per room."""
    critic_batch: int = 4
    task_objects: bool = True
    """Place the task's objects read from the request (off when they already exist)."""
    extra_fill: int = 6
    critic_scope: str = "local"
    """What the placement critic simulates: ``local`` (the candidate and what it can touch;
    the whole scene's verdicts at a cost that does not grow with the scene) or ``scene``."""
    workers: int | None = None
    """Processes for the rooms of a multi-room home (:mod:`.per_room`; ``None``: one per room
    up to the CPU cores; 1: one after the other in this process). The scene is the same."""


@dataclass
class Trace:
    """Tool calls and their results."""

    calls: list[dict[str, Any]] = field(default_factory=list)


Caller = Callable[..., dict[str, Any]]


def _count(item: Item, rng: np.random.Generator) -> int:
    if item.p < 1.0 and rng.uniform() > item.p:
        return 0
    return int(rng.integers(item.count[0], item.count[1] + 1))


@dataclass
class BrainState:
    """What the heuristic brain carries from one step to the next (picklable: a room's state
    goes to a worker process and back).

    Attributes:
        rng: the brain's random stream (counts, filler order).
        style: the request's style word, put before every asset text ("" for none).
        budget: the most objects the scene gets.
        keyed: ``"<room id>:<key>" -> object ids`` placed under a rule key (supports).
        small: ``(item, count, "<room id>:<support key>")`` still to place on surfaces.
        stored: ``(item, "<room id>:<key>")`` still to store inside (``in:<key>``; counted
            when placed, last, so that the stream's earlier draws stay as they were).
        n_objects: objects in the scene after the last placement.
        room_type: the last furnished room's type (its fillers close the scene).
    """

    rng: np.random.Generator
    style: str
    budget: int
    keyed: dict[str, list[str]] = field(default_factory=dict)
    small: list[tuple[Item, int, str]] = field(default_factory=list)
    stored: list[tuple[Item, str]] = field(default_factory=list)
    n_objects: int = 0
    room_type: str | None = None


class Brain:
    """The heuristic brain's steps over a tool caller, each reading and updating ``state``.

    :func:`~.brain.heuristic_agent` runs them in order on one scene; :mod:`.per_room` runs
    them room by room (:meth:`furnish` and :meth:`drop_unstable`, then :meth:`task_objects` on the
    whole home, then :meth:`small_objects`, :meth:`fill` and :meth:`stored_objects`).

    Args:
        call: ``call(tool_name, **arguments) -> result dict``.
        cfg: the agent's knobs.
        state: the brain's state.
    """

    def __init__(self, call: Caller, cfg: AgentConfig, state: BrainState) -> None:
        self.call = call
        self.cfg = cfg
        self.state = state

    def styled(self, text: str) -> str:
        return f"{self.state.style} {text}" if self.state.style else text

    def place(self, **args: Any) -> dict[str, Any]:
        res = self.call("place_objects", **args)
        self.state.n_objects = int(res.get("objects", self.state.n_objects))
        return res

    def furnish(self, rooms: list[dict[str, Any]]) -> None:
        """Step 1: floor and wall furniture, room by room; small items are queued."""
        st = self.state
        for room in rooms:
            rt = ROOM_TYPES[room["room_type"]]
            st.room_type = room["room_type"]
            for item in rt.items:
                if item.rule.startswith("in:"):
                    st.stored.append((item, f"{room['id']}:{item.rule.split(':', 1)[1]}"))
                    continue
                n = _count(item, st.rng)
                key = f"{room['id']}:{item.key}" if item.key else ""
                if item.rule.startswith("on:"):
                    st.small.append((item, n, f"{room['id']}:{item.rule.split(':', 1)[1]}"))
                    continue
                rule, _, ref = item.rule.partition(":")
                for _ in range(n):
                    targets = st.keyed.get(f"{room['id']}:{ref}", [])
                    if rule in ("near", "around") and not targets:
                        break
                    if rule == "mount":
                        res = self.place(
                            text=self.styled(item.text),
                            placement="wall",
                            height=item.height,
                            room_id=room["id"],
                        )
                    else:
                        res = self.place(
                            text=self.styled(item.text),
                            placement="floor",
                            rule=rule,
                            target=targets[0] if targets else None,
                            room_id=room["id"],
                        )
                    if res.get("ok") and key:
                        st.keyed.setdefault(key, []).extend(res["placed"])

    def drop_unstable(self) -> None:
        """Step 2: simulate once; drop unstable floor furniture (the paper's shortcut)."""
        physics = self.call("physics_critic")
        for oid in physics.get("unstable", []):
            self.call("remove_object", object_id=oid)
        alive = {o["id"] for o in self.call("get_scene_info").get("objects", [])}
        self.state.keyed = {k: [i for i in v if i in alive] for k, v in self.state.keyed.items()}

    def task_objects(self, request: str, task: str | None) -> TaskSpec | PartSpec | None:
        """Step 3: the task's objects first: on the support the request picks from, else on
        the largest table-like surface; a travelling task's place support apart
        (:meth:`two_supports`); an open or close task's object (:meth:`openable`).

        Raises:
            ConfigError: an open or close task names an object that does not open or that
                the request's rooms do not hold (:func:`~.part_read.check_part_request`).
        """
        spec: TaskSpec | PartSpec | None = None
        if self.cfg.task_objects:  # the request's own task is read from its English reading
            spec = request_task(request, task)
        if spec is None:
            return None
        if isinstance(spec, PartSpec):
            check_part_request(spec, parse_request(request).room_types)
            self.openable(spec)
            self.put_away_item(spec)
            return spec
        objects = self.call("get_scene_info")["objects"]
        if spec.travel:
            self.two_supports(spec, objects)
            return spec
        table = self.pick_support(spec, objects)
        if table is not None:
            for text, role in ((spec.target, "place_target"), (spec.pick, "pick")):
                self.place(text=text, placement="on_top", target=table["id"], task_role=role)
        return spec

    def openable(self, spec: PartSpec) -> None:
        """The object an open or close task names, where the room program places none (it
        may queue one for a counter, a microwave, placed later): against a wall, or on the
        largest table-like support for a countertop object (the catalogue's ``placement``).
        The task's feasibility critic then judges whether the robot can work its part
        (``stage=generate``'s last step)."""
        from factory.assets.catalog import CATEGORIES

        if not spec.category:
            return
        objects = self.call("get_scene_info")["objects"]
        if any(o["category"] == spec.category for o in objects):
            return
        queued = [  # the room program's countertop items come later (small_objects)
            item
            for item, n, _ in self.state.small
            if n > 0 and openable_category(catalogue_category(item.text)) == spec.category
        ]
        if queued:
            return
        cat = CATEGORIES[spec.category]
        text = spec.named or spec.category.replace("_", " ")
        if cat.placement == "on_top":
            # table-like supports and the articulated ones standing for them (base_cabinet)
            counters = {*TABLES, *(openable_category(t) for t in TABLES)}
            tables = [o for o in objects if o["category"] in counters]
            if tables:
                best = max(tables, key=lambda o: o["size"][0] * o["size"][1])
                res = self.place(text=text, placement="on_top", target=best["id"])
                if res.get("ok"):
                    return
        for rule in ("wall", "free"):
            if self.place(text=text, placement="floor", rule=rule).get("ok"):
                return
        log.warning("request %r: could not place the %s it names", spec.instruction, text)

    def put_away_item(self, spec: PartSpec) -> None:
        """The object a "put the mug in the drawer" request puts away (``PartSpec.item``), on
        the largest table-like support, else (a bedroom without a desk) on the largest object
        holding the drawer (``PartSpec.category``: the nightstand), marked ``pick`` (the
        task's set-up moves it onto the drawer's top)."""
        if not spec.item_named:
            return
        objects = self.call("get_scene_info")["objects"]
        tables = [o for o in objects if o["category"] in TABLES]
        holders = [o for o in objects if o["category"] == spec.category]
        for group in (tables, holders):
            if not group:
                continue
            best = max(group, key=lambda o: o["size"][0] * o["size"][1])
            res = self.place(
                text=spec.item_named, placement="on_top", target=best["id"], task_role="pick"
            )
            if res.get("ok"):
                return
        log.warning(
            "request %r: could not place the %s it names", spec.instruction, spec.item_named
        )

    def pick_support(self, spec: TaskSpec, objects: list[dict[str, Any]]) -> dict[str, Any] | None:
        """The support the object is picked from: the one "from the <source>" names (placed
        against a wall when the room has none), else the largest table-like surface (a dining
        table placed in the middle when there is none)."""
        if spec.source:
            found = _named(spec.source, objects)
            if found is not None:
                return found
            res = self.place(text=spec.source, placement="floor", rule="wall")
            if res.get("ok"):
                return {"id": res["placed"][0], "size": [1, 1, 1]}
        tables = [o for o in objects if o["category"] in TABLES]
        if not tables:
            res = self.place(text="dining table", placement="floor", rule="center")
            tables = [{"id": res["placed"][0], "size": [1, 1, 1]}] if res.get("ok") else []
        return max(tables, key=lambda o: o["size"][0] * o["size"][1]) if tables else None

    def two_supports(self, spec: TaskSpec, objects: list[dict[str, Any]]) -> None:
        """ "Move X from A to B": X on support A, and B a support of its own away from A,
        marked ``place_support`` for the mobile task, where the route check passes
        (:meth:`keep_route`)."""
        source = self.pick_support(spec, objects)
        if source is None:
            return
        self.place(text=spec.pick, placement="on_top", target=source["id"], task_role="pick")
        spots = self.support_spots(spec.target, source["id"])
        if spots and spots[0][0] is None:  # both in one room: the source goes to a wall
            # first, so that the place support can stand far from it (a coffee table in the
            # middle of a 5 m room leaves no spot 1.5 m from its edges); what stands on it
            # moves along
            self.call("move_object", object_id=source["id"], placement="floor", rule="wall")
        for room_id, rule in spots:
            res = self.place(
                text=spec.target,
                placement="floor",
                rule=rule,
                target=source["id"],
                task_role="place_support",
                room_id=room_id,
            )
            if res.get("ok"):
                self.keep_route()
                return

    def support_spots(self, text: str, source_id: str) -> list[tuple[str | None, str]]:
        """Where the place support (``text``) may go, best first, as ``(room id, rule)``: in a
        home, first the other rooms whose furniture it is (a desk in the study: the route
        then passes a door), against a wall, facing the source, or anywhere about 2.5 m from
        it; then the source's own room: anywhere about 2.4 m between the edges (out of the pick
        pose's reach: :data:`~factory.nav.support_gap.MIN_SUPPORT_GAP`), facing the source
        from a wall (about 2.5 m away), against a wall, or anywhere free."""
        info = self.call("get_scene_info")
        rooms = info.get("rooms", [])
        home = next(
            (o.get("room_id") for o in info.get("objects", []) if o["id"] == source_id), None
        )
        near: tuple[str, ...] = ("facing", "away", "wall", "free")
        if len(rooms) <= 1 or home is None:
            return [(None, rule) for rule in near]

        def holds(room: dict[str, Any]) -> bool:
            rt = ROOM_TYPES.get(room["room_type"])
            return rt is not None and any(
                it.text == text or it.text.endswith(f" {text}") for it in rt.items
            )

        out: list[tuple[str | None, str]] = [
            (r["id"], rule)
            for r in rooms
            if r["id"] != home and holds(r)
            for rule in ("wall", "facing", "away")
        ]
        return out + [(home, rule) for rule in near]

    def keep_route(self) -> dict[str, Any]:
        """The mobile task's route check (``route_critic``) and its repair. When the check
        fails, a pick support that the base cannot work at moves (with what stands on it)
        towards the middle of its room or anywhere free; the place support moves through
        :meth:`support_spots` (same asset and id, what stands on it along) until the check
        passes; when no spot is far enough from the source, up to :data:`MAX_MADE_ROOM`
        light floor objects far from it are taken out to make room (:meth:`make_room`);
        when the way is blocked, the light floor objects the check names are taken out.
        Nothing happens for a scene without a mobile task.

        Returns:
            the last verdict.
        """
        from factory.nav.route import BLOCKED, NO_PICK_POSE, PLACE_SUPPORT_TOO_CLOSE

        verdict = self.call("route_critic")
        if not verdict.get("ok") or not verdict.get("applies") or not verdict.get("reason"):
            return verdict
        place, source = verdict.get("place_support"), verdict.get("pick_support")
        if place and source:
            objects = {o["id"]: o for o in self.call("get_scene_info").get("objects", [])}

            def free_pick_side(verdict: dict[str, Any]) -> dict[str, Any]:
                """The pick's support moved (centre, then anywhere) where the base has no
                pose to pick from: the place support stands next to it."""
                if verdict.get("reason") == NO_PICK_POSE and source in objects:
                    room = objects[source].get("room_id")
                    for rule in ("center", "free"):
                        verdict = self.move_support(source, room, rule, None, verdict)
                        if not verdict.get("reason"):
                            break
                return verdict

            verdict = free_pick_side(verdict)
            if not verdict.get("reason"):
                return verdict
            text = str(objects[place]["category"]).replace("_", " ") if place in objects else ""
            spots = self.support_spots(text, source) if text else []
            for room_id, rule in spots:
                verdict = self.move_support(place, room_id, rule, source, verdict)
                if not verdict.get("reason"):
                    return verdict
            if verdict.get("reason") == PLACE_SUPPORT_TOO_CLOSE:
                verdict = self.make_room(place, source, [r for r, _ in spots], verdict)
            verdict = free_pick_side(verdict)
            if not verdict.get("reason"):
                return verdict
        if verdict.get("reason") in BLOCKED:
            verdict = self.call("route_critic", clear=True)
            for oid in verdict.get("clear", []):
                self.call("remove_object", object_id=oid)
            if verdict.get("clear"):
                verdict = self.call("route_critic")
        if verdict.get("reason"):
            log.info("the mobile task's route check fails: %s", verdict.get("detail"))
        return verdict

    def move_support(
        self,
        oid: str,
        room_id: str | None,
        rule: str,
        target: str | None,
        verdict: dict[str, Any],
    ) -> dict[str, Any]:
        """Moves a task support to ``(room_id, rule)`` (``target`` for the rules that need
        one) and checks the route again; the verdict of the new spot, or ``verdict`` when it
        could not move."""
        moved = self.call(
            "move_object",
            object_id=oid,
            placement="floor",
            rule=rule,
            target=target,
            room_id=room_id,
        )
        return self.call("route_critic") if moved.get("ok") else verdict

    def make_room(
        self, place: str, source: str, rooms: list[str | None], verdict: dict[str, Any]
    ) -> dict[str, Any]:
        """Takes out light floor objects (at most 1 m across, no task role) that stand far
        enough from the source, the largest first, one at a time (up to
        :data:`MAX_MADE_ROOM`), each time moving the place support about 2.5 m from the
        source, until the route check passes."""
        from factory.nav.route import MIN_SUPPORT_SEPARATION

        info = self.call("get_scene_info")
        objects = {o["id"]: o for o in info.get("objects", [])}
        home = objects[source].get("room_id") if source in objects else None
        where = [r if r is not None else home for r in rooms] or [home]
        sx, sy = objects[source]["position"][:2] if source in objects else (0.0, 0.0)

        def light(o: dict[str, Any]) -> bool:
            far = math.hypot(o["position"][0] - sx, o["position"][1] - sy)
            return (
                o["placement"] == "floor"
                and not o.get("task_role")
                and o["id"] not in (place, source)
                and max(o["size"][0], o["size"][1]) <= 1.0
                and far >= MIN_SUPPORT_SEPARATION
                and o.get("room_id") in where
            )

        pool = sorted(
            (o for o in objects.values() if light(o)),
            key=lambda o: (where.index(o.get("room_id")), -o["size"][0] * o["size"][1], o["id"]),
        )
        for o in pool[:MAX_MADE_ROOM]:
            self.call("remove_object", object_id=o["id"])
            for rule in ("away", "facing"):
                verdict = self.move_support(place, o.get("room_id"), rule, source, verdict)
                if not verdict.get("reason"):
                    return verdict
        return verdict

    def small_objects(self) -> None:
        """Step 4: small objects on surfaces, multi-level, each judged by the physics critic."""
        st = self.state
        for item, n, ref in st.small:
            supports = st.keyed.get(ref, [])
            key = f"{ref.split(':', 1)[0]}:{item.key}" if item.key else ""
            for k in range(n):
                if not supports or st.n_objects >= st.budget:
                    break
                res = self.place(
                    text=self.styled(item.text),
                    placement="on_top",
                    target=supports[k % len(supports)],
                )
                if res.get("ok") and key:  # e.g. a microwave on the counter, stocked later
                    st.keyed.setdefault(key, []).extend(res["placed"])
        st.small = []

    def stored_objects(self) -> None:
        """Step 6: things stored inside articulated furniture (``in:<key>``: behind a door, in
        a drawer), each judged by the physics critic; where ``<key>`` has no interiors (a rigid
        asset), nothing is placed."""
        st = self.state
        for item, ref in st.stored:
            supports = st.keyed.get(ref, [])
            for k in range(_count(item, st.rng) if supports else 0):
                if st.n_objects >= st.budget:
                    break
                self.place(
                    text=self.styled(item.text),
                    placement="inside",
                    target=supports[k % len(supports)],
                )
        st.stored = []

    def fill(self) -> None:
        """Step 5: the visual critic's suggestions (companions, sparse areas), then fillers
        of the last furnished room's type."""
        st = self.state
        for suggestion in self.call("visual_critic").get("suggestions", [])[: self.cfg.extra_fill]:
            args = dict(suggestion["call"]["args"])
            if suggestion["call"]["tool"] != "place_objects" or "text" not in args:
                continue
            if st.n_objects >= st.budget:
                break
            args["text"] = self.styled(args["text"])
            self.place(**args)
        if st.room_type is None:
            return
        fillers = list(ROOM_TYPES[st.room_type].fillers) * 2
        st.rng.shuffle(fillers)
        for text in fillers[: self.cfg.extra_fill]:
            if st.n_objects >= st.budget:
                break
            self.place(
                text=self.styled(text),
                placement="floor",
                rule="corner" if st.rng.uniform() < 0.5 else "wall",
            )


def _named(text: str, objects: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The largest object whose category is ``text`` or ends with it ("table": a coffee
    table), or None."""
    key = text.replace(" ", "_")
    hits = [o for o in objects if o["category"] == key or o["category"].endswith(key)]
    return max(hits, key=lambda o: o["size"][0] * o["size"][1]) if hits else None


TABLES = (
    "dining_table",
    "coffee_table",
    "desk",
    "kitchen_island",
    "side_table",
    "conference_table",
    "console_table",
    "kitchen_cabinet",
    "workbench",
)


def task_kind(spec: dict[str, Any]) -> str:
    """The scene's ``Task.kind`` for a parsed task (``TaskSpec`` fields): the registered task
    whose :meth:`~factory.tasks.base.Task.matches_request` takes it ("move X from A to B", two
    supports apart: the mobile task), else the default task."""
    from factory.tasks import DEFAULT_TASK, tasks

    return next((t.name for t in tasks() if t.matches_request(spec)), DEFAULT_TASK)


def brief(result: dict[str, Any]) -> dict[str, Any]:
    """A result short enough for the trace (object lists are summarised)."""
    if "objects" in result and isinstance(result["objects"], list):
        return {**result, "objects": len(result["objects"])}
    return result
