"""The heuristic brain's steps: its knobs, its state and the tool calls of each step.

:class:`Brain` holds the steps of the paper's loop over any tool caller (a
:class:`~.tools.ToolSession`, or an MCP client): furnish the rooms, drop unstable furniture,
place the task's objects, put small objects on surfaces with the physics critic judging each,
then the visual critic's suggestions and fillers. :func:`~.brain.heuristic_agent` runs them on
one scene; :mod:`.per_room` runs them room by room.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.scenes.request import TaskSpec, parse_request, parse_task
from factory.scenes.rooms import ROOM_TYPES, Item


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
        n_objects: objects in the scene after the last placement.
        room_type: the last furnished room's type (its fillers close the scene).
    """

    rng: np.random.Generator
    style: str
    budget: int
    keyed: dict[str, list[str]] = field(default_factory=dict)
    small: list[tuple[Item, int, str]] = field(default_factory=list)
    n_objects: int = 0
    room_type: str | None = None


class Brain:
    """The heuristic brain's steps over a tool caller, each reading and updating ``state``.

    :func:`~.brain.heuristic_agent` runs them in order on one scene; :mod:`.per_room` runs
    them room by room (:meth:`furnish` and :meth:`drop_unstable`, then :meth:`task_objects` on the
    whole home, then :meth:`small_objects` and :meth:`fill`).

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

    def task_objects(self, request: str, task: str | None) -> TaskSpec | None:
        """Step 3: the task's objects first, on the largest table-like surface."""
        spec = None
        if self.cfg.task_objects:  # the request's own task is read from its English reading
            spec = parse_task(task) if task else parse_request(request).task
        if spec is None:
            return None
        objects = self.call("get_scene_info")["objects"]
        if spec.source:
            self.two_supports(spec, objects)
            return spec
        tables = [o for o in objects if o["category"] in TABLES]
        if not tables:
            res = self.place(text="dining table", placement="floor", rule="center")
            tables = [{"id": res["placed"][0], "size": [1, 1, 1]}] if res.get("ok") else []
        if tables:
            table = max(tables, key=lambda o: o["size"][0] * o["size"][1])
            for text, role in ((spec.target, "place_target"), (spec.pick, "pick")):
                self.place(text=text, placement="on_top", target=table["id"], task_role=role)
        return spec

    def two_supports(self, spec: TaskSpec, objects: list[dict[str, Any]]) -> None:
        """ "Move X from A to B": X on support A, and B a support of its own away from A
        (about 2.5 m: the ``facing`` rule), marked ``place_support`` for the mobile task."""

        def named(text: str) -> dict[str, Any] | None:
            key = text.replace(" ", "_")
            hits = [o for o in objects if o["category"] == key or o["category"].endswith(key)]
            return max(hits, key=lambda o: o["size"][0] * o["size"][1]) if hits else None

        source = named(spec.source)
        if source is None:
            res = self.place(text=spec.source, placement="floor", rule="wall")
            source = {"id": res["placed"][0]} if res.get("ok") else None
        if source is None:
            return
        self.place(text=spec.pick, placement="on_top", target=source["id"], task_role="pick")
        for rule in ("facing", "wall", "free"):  # away from A first, then anywhere free
            res = self.place(
                text=spec.target,
                placement="floor",
                rule=rule,
                target=source["id"],
                task_role="place_support",
            )
            if res.get("ok"):
                return

    def small_objects(self) -> None:
        """Step 4: small objects on surfaces, multi-level, each judged by the physics critic."""
        st = self.state
        for item, n, ref in st.small:
            supports = st.keyed.get(ref, [])
            for k in range(n):
                if not supports or st.n_objects >= st.budget:
                    break
                self.place(
                    text=self.styled(item.text),
                    placement="on_top",
                    target=supports[k % len(supports)],
                )
        st.small = []

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


def brief(result: dict[str, Any]) -> dict[str, Any]:
    """A result short enough for the trace (object lists are summarised)."""
    if "objects" in result and isinstance(result["objects"], list):
        return {**result, "objects": len(result["objects"])}
    return result
