"""Which task's features a dataset holds: an episode's task, a dataset's layout, one per dataset.

Every task's episodes are exported by one path with the features the task declares
(:meth:`~factory.tasks.base.Task.dataset_features`); tasks whose features differ have different
layouts (:meth:`~factory.tasks.base.Task.dataset_layout`: ``fixed``, ``mobile``), written as
``layout`` in ``meta/factory.json`` by the tasks that add it
(:meth:`~factory.tasks.base.Task.dataset_meta`; absent: the default task's). One dataset holds
one layout: :func:`one_layout` refuses an export, :func:`one_meta_layout` a merge, that mixes
them.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from factory.errors import MixedLayoutError, StoreError
from factory.tasks import DEFAULT_TASK, TASKS, get_task, task_names

if TYPE_CHECKING:
    from factory.tasks.base import Task


@dataclass(frozen=True)
class EpisodeLayout:
    """The layout of one episode.

    Attributes:
        episode_id: the episode.
        task: its ``EpisodeInfo.task``.
        layout: its task's :meth:`~factory.tasks.base.Task.dataset_layout`.
    """

    episode_id: str
    task: str
    layout: str


def episode_task(info: Any) -> Task:
    """The task whose features an episode is exported with: the registered task its
    ``EpisodeInfo.task`` names, else the default task."""
    return get_task(info.task if info.task in TASKS else DEFAULT_TASK)


def layout_of(info: Any) -> EpisodeLayout:
    """The layout of an episode (``info``: its ``EpisodeInfo``)."""
    return EpisodeLayout(info.episode_id, info.task, episode_task(info).dataset_layout())


def _in_registry_order(layouts: Iterable[str]) -> list[str]:
    """``layouts`` in the order of the registered tasks that write them (unknown ones last):
    the order the mixed-layout errors name them in."""
    known = list(dict.fromkeys(get_task(n).dataset_layout() for n in task_names()))
    return sorted(layouts, key=lambda lay: known.index(lay) if lay in known else len(known))


def one_layout(layouts: Iterable[EpisodeLayout]) -> str:
    """The single layout of a dataset's episodes.

    Raises:
        MixedLayoutError: layouts are mixed (names an episode of two of them and the fix).
    """
    first: dict[str, EpisodeLayout] = {}
    for lay in layouts:
        first.setdefault(lay.layout, lay)
    if len(first) > 1:
        a, b = (first[lay] for lay in _in_registry_order(first)[:2])
        raise MixedLayoutError(
            f"episode {a.episode_id!r} (task {a.task!r}, {a.layout} base) and episode "
            f"{b.episode_id!r} (task {b.task!r}, {b.layout} base) cannot share one "
            "dataset: their features differ. Record each task in its own run_dir (stage=demos "
            "task=... run_dir=...) and export each with stage=dataset"
        )
    return next(iter(first), _default_layout())


def _default_layout() -> str:
    return get_task(DEFAULT_TASK).dataset_layout()


def meta_layout(meta: dict[str, Any]) -> str:
    """The layout recorded in a dataset's ``meta/factory.json`` (the default task's when
    absent)."""
    return str(meta.get("layout", _default_layout()))


def layout_task(layout: str) -> Task:
    """The first registered task whose datasets have ``layout``.

    Raises:
        StoreError: no registered task has it (names the layouts there are).
    """
    for name in task_names():
        task = get_task(name)
        if task.dataset_layout() == layout:
            return task
    raise StoreError(
        f"no registered task writes datasets of layout {layout!r}: the layouts are "
        f"{', '.join(get_task(n).dataset_layout() for n in task_names())} (export the dataset "
        "with this factory's stage=dataset)"
    )


def meta_task(meta: dict[str, Any]) -> Task:
    """The task whose features a dataset holds (its ``meta/factory.json``'s layout)."""
    return layout_task(meta_layout(meta))


def one_meta_layout(metas: list[dict[str, Any]], names: list[str]) -> str:
    """The single layout of datasets to merge (``names``: their folders, for the message).

    Raises:
        MixedLayoutError: datasets of different layouts are mixed.
    """
    kinds = {meta_layout(m): n for m, n in zip(metas, names, strict=True)}
    if len(kinds) > 1:
        a, b = _in_registry_order(kinds)[:2]
        raise MixedLayoutError(
            f"{kinds[a]} holds {a}-base episodes and {kinds[b]} {b} ones: they "
            "cannot be merged into one dataset. Record each task in its own run_dir and export "
            "each with stage=dataset"
        )
    return next(iter(kinds), _default_layout())


def task_meta_of(meta: dict[str, Any]) -> dict[str, Any]:
    """The keys a dataset's task added to its ``meta/factory.json``, to carry into a merge
    (:meth:`~factory.tasks.base.Task.dataset_meta`; values as the dataset holds them)."""
    return {k: meta.get(k, v) for k, v in meta_task(meta).dataset_meta().items()}
