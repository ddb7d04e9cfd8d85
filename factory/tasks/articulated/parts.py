"""The moving parts of a scene that the articulated tasks act on, and which one an episode's
request names.

A *part* is a joint of an articulated object (``meta.json``'s ``articulation``, built with
``assets.articulated=true``) whose link carries a graspable handle (``HandleMeta``). Parts are
read from the run's assets; each gets a label the instruction uses ("the door of the fridge",
"the top drawer of the base cabinet"): the role word (``door``, ``drawer``, ``flap`` is called
a door, ``lid``, ``seat``), a qualifier where the object has several parts of one role (top /
middle / bottom by handle height for drawers, left / right as seen from the front for the
others) and the object's category.

Which part a scene's episodes act on (:func:`choose_parts`), first match wins:

1. an object's ``task_joint`` (the scene names the joint outright);
2. the scene's ``task.instruction`` when it names a part: its words must hold the role word,
   a word of the object's category (``fridge`` for ``upright_fridge``, ``nightstand`` for
   ``bedside_cabinet``: :func:`category_words`) unless it names no object at all ("open the
   top drawer": any object's), and, where given, the qualifier, which an object's only part
   of that role also meets when no part matches it outright ("the top drawer of the
   nightstand": its one drawer); a request that names a part no object has is an error
   listing the parts;
3. otherwise (a generated kitchen made for another task) every part, in the scene's object
   order: the set-up (:func:`factory.tasks.articulated.plan.setup_scene`) takes the first one
   the robot can work from a free base spot.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from factory.errors import TaskError
from factory.schema import Scene, SceneObject
from factory.schema.asset import AssetMeta, HandleMeta, JointMeta

__all__ = ["Part", "choose_parts", "part_label", "scene_parts"]

ROLE_WORDS: dict[str, str] = {
    "door": "door",
    "drawer": "drawer",
    "flap": "door",
    "lid": "lid",
    "seat": "seat",
}
"""Joint role -> the word an instruction calls its part by."""

CATEGORY_NOISE = frozenset({"upright", "base", "oven", "unit", "small", "large", "built", "in"})
"""Category words an instruction need not say ("the fridge" is the ``upright_fridge``; "the
microwave" the ``microwave_oven``)."""

SYNONYMS: dict[str, tuple[str, ...]] = {
    "fridge": ("fridge", "refrigerator"),
    "cabinet": ("cabinet", "cupboard"),
    "microwave": ("microwave",),
    "chest": ("chest", "dresser"),
}
"""A category word -> the words an instruction may use for it."""


@dataclass(frozen=True)
class Part:
    """One graspable moving part of a scene.

    Attributes:
        obj: the articulated object.
        joint: its joint (asset frame: ``anchor`` m, ``axis``, ``range`` rad or m, unscaled).
        handle: the handle on the joint's link (object frame, closed pose, unscaled).
        scale: the object's asset scale (x, y, z).
        label: what the instruction calls it ("the top drawer of the base cabinet").
    """

    obj: SceneObject
    joint: JointMeta
    handle: HandleMeta
    scale: tuple[float, float, float]
    label: str

    @property
    def joint_name(self) -> str:
        """The compiled joint's name (``<object id>/<joint>``)."""
        return f"{self.obj.id}/{self.joint.name}"

    @property
    def body_name(self) -> str:
        """The compiled link body's name (``<object id>/<link>``)."""
        return f"{self.obj.id}/{self.joint.link}"

    @property
    def key(self) -> str:
        """``<object id>:<joint>`` (how logs and reasons name it)."""
        return f"{self.obj.id}:{self.joint.name}"

    def handle_in_link(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The handle's centre (m), long axis and outward normal in the link body's frame
        (which is the object frame in the closed pose), the asset's scale applied."""
        s = np.array(self.scale, float)
        center = np.array(self.handle.center, float) * s
        along = np.array(self.handle.along, float) * s
        normal = np.array(self.handle.normal, float) / s
        return center, along / np.linalg.norm(along), normal / np.linalg.norm(normal)


def _words(text: str) -> list[str]:
    return re.findall(r"[a-z]+", text.lower())


@cache
def category_words(category: str) -> tuple[str, ...]:
    """The words of ``category`` an instruction names the object by: its name's words (with
    :data:`SYNONYMS`) and the head word of every catalogue name and synonym of the category
    and of the rigid categories that stand for it (``nightstand`` for the
    ``bedside_cabinet``, ``closet`` for the ``built_in_wardrobe``)."""
    from factory.assets.catalog import CATEGORIES

    out: list[str] = []
    for w in category.split("_"):
        if w in CATEGORY_NOISE or w in ROLE_WORDS:  # "drawer" of drawer_chest names no chest
            continue
        out.extend(SYNONYMS.get(w, (w,)))
    for name, cat in CATEGORIES.items():
        if name != category and cat.articulated_as != category:
            continue
        for phrase in (name.replace("_", " "), *cat.synonyms):
            words = phrase.lower().replace("-", " ").split(" of ")[0].split()
            head = words[-1] if words else ""
            if head and head not in CATEGORY_NOISE and head not in ROLE_WORDS:
                out.append(head)
    return tuple(dict.fromkeys(out)) or (category,)


def part_label(
    obj: SceneObject, joint: JointMeta, siblings: list[tuple[JointMeta, HandleMeta]]
) -> str:
    """The label of ``obj``'s part moved by ``joint`` among the object's handled parts
    ``siblings`` (joint, handle) (see the module docstring)."""
    word = ROLE_WORDS.get(joint.role, joint.role)
    same = [(j, h) for j, h in siblings if ROLE_WORDS.get(j.role, j.role) == word]
    qual = ""
    if len(same) > 1:
        own = next(h for j, h in same if j.name == joint.name)
        if word == "drawer":
            heights = sorted(h.center[2] for _, h in same)
            rank = heights.index(own.center[2])
            qual = "bottom" if rank == 0 else "top" if rank == len(heights) - 1 else "middle"
        else:
            # seen from the front (the handle's normal points at the viewer, who looks along
            # -normal): the viewer's right is (-normal) x up = up x normal
            n = np.array(own.normal, float)
            right = np.cross([0.0, 0.0, 1.0], n)
            side = [float(np.dot(h.center, right)) for _, h in same]
            mine = float(np.dot(own.center, right))
            qual = (
                "right"
                if mine >= max(side) - 1e-9
                else "left"
                if mine <= min(side) + 1e-9
                else "middle"
            )
    name = obj.category.replace("_", " ")
    return f"the {qual + ' ' if qual else ''}{word} of the {name}"


def scene_parts(scene: Scene, assets_root: str | Path | None) -> list[Part]:
    """Every graspable moving part of ``scene`` (objects in scene order, joints in asset
    order): joints whose link carries a handle, of objects whose asset is in
    ``assets_root`` with an ``articulation``."""
    from factory.assets.cache import cached

    if assets_root is None:
        return []
    root = Path(assets_root)
    out: list[Part] = []
    for obj in scene.objects:
        if obj.asset is None or not obj.asset.asset_id:
            continue
        meta: AssetMeta | None = cached(root, obj.asset.asset_id)
        if meta is None or meta.articulation is None:
            continue
        art = meta.articulation
        handled: list[tuple[JointMeta, HandleMeta]] = []
        for joint in art.joints:
            link = art.link(joint.link)
            if link.handles:
                handled.append((joint, link.handles[0]))
        sc = obj.asset.scale
        scale = (float(sc.x), float(sc.y), float(sc.z))
        for joint, handle in handled:
            out.append(Part(obj, joint, handle, scale, part_label(obj, joint, handled)))
    return out


def names_part(text: str, part: Part, role: str | None = None) -> bool:
    """Whether the instruction ``text`` names ``part``: its role word (or ``role``, the role
    the text implies without saying it: "put the mug in the microwave" means its ``door``); a
    word of the object's category (:func:`category_words`), or no object at all ("open the
    top drawer": any object's); and the qualifier where the text gives one."""
    from factory.scenes.part_read import read_part_task

    words = set(_words(text))
    label = _words(part.label)
    word = ROLE_WORDS.get(part.joint.role, part.joint.role)
    if word not in words and f"{word}s" not in words and word != role:
        return False
    if not words & set(category_words(part.obj.category)):
        spec = read_part_task(text)
        if spec is None or (spec.named and spec.category != part.obj.category):
            return False
    quals = {"top", "middle", "bottom", "left", "right", "upper", "lower"}
    asked = words & quals
    if not asked:
        return True
    asked = {"top" if w == "upper" else "bottom" if w == "lower" else w for w in asked}
    return bool(asked & set(label))


def _sole_of_role(text: str, parts: list[Part]) -> list[Part]:
    """The parts ``text`` names but for its qualifier that are the only part of their role
    on their object ("the top drawer of the nightstand": its one drawer, over its door)."""
    out = []
    for p in parts:
        word = ROLE_WORDS.get(p.joint.role, p.joint.role)
        unqualified = re.sub(r"\b(?:top|middle|bottom|left|right|upper|lower)\b", " ", text)
        if p.label.startswith(f"the {word} of") and names_part(unqualified, p):
            out.append(p)
    return out


def choose_parts(scene: Scene, assets_root: str | Path | None) -> list[Part]:
    """The parts an episode of ``scene`` may act on, best first (see the module docstring).

    Raises:
        TaskError: the scene has no graspable moving part (built without
            ``assets.articulated=true``?), its ``task_joint`` names no handled joint, or its
            instruction names a part it does not have (the message lists its parts).
    """
    parts = scene_parts(scene, assets_root)
    if not parts:
        raise TaskError(
            f"scene {scene.id!r} has no articulated object with a handle (generate it with "
            "assets.articulated=true: cabinets, fridge, microwave, drawer chests)"
        )
    listing = "; ".join(f"{p.key} ({p.label})" for p in parts)
    named = [o for o in scene.objects if o.task_joint]
    if named:
        chosen = [
            p for p in parts for o in named if p.obj.id == o.id and p.joint.name == o.task_joint
        ]
        if not chosen:
            asked = ", ".join(f"{o.id}:{o.task_joint}" for o in named)
            raise TaskError(
                f"scene {scene.id!r}: task_joint {asked} is no handled joint of the scene; "
                f"its parts: {listing}"
            )
        return chosen
    text = scene.task.instruction if scene.task is not None else ""
    words = set(_words(text))
    mentions_part = bool(words & {*ROLE_WORDS.values(), *(f"{w}s" for w in ROLE_WORDS.values())})
    if text and mentions_part:
        chosen = [p for p in parts if names_part(text, p)] or _sole_of_role(text, parts)
        if not chosen:
            raise TaskError(
                f"scene {scene.id!r}: the instruction {text!r} names no part of the scene; "
                f"its parts: {listing}"
            )
        return chosen
    return parts
