"""Which task an evaluation runs: the one asked for (``task=``), the one whose dataset it
evaluates on, the one the policy was trained on.

The default task (:data:`factory.tasks.DEFAULT_TASK`, what ``task=`` is when nobody set it)
yields to the dataset's and the policy's; another task asked for is kept, and a dataset or a
policy of another task is refused. Datasets tell their task by their layout
(``meta/factory.json``, :func:`factory.dataset.layout.meta_task`), policies by the layout of
the dataset they were trained on (``TrainInfo.layout``) or, in policies trained before it was
recorded, by the features they read (:meth:`~factory.tasks.base.Task.claims_features`).
"""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from factory.errors import PolicyError
from factory.tasks import DEFAULT_TASK, get_task, tasks

if TYPE_CHECKING:
    from factory.tasks.base import Task


def policy_task(features: Collection[str], layout: str = "") -> Task:
    """The task whose datasets a policy reading ``features`` was trained on: the task of its
    dataset's ``layout`` where the policy recorded it, else the first registered task that
    claims the features, else the default task."""
    if layout:
        from factory.dataset.layout import layout_task

        return layout_task(layout)
    for task in tasks():
        if task.claims_features(features):
            return task
    return get_task(DEFAULT_TASK)


def evaluated_task(
    task: str,
    meta: dict[str, Any] | None,
    features: Collection[str] | None = None,
    layout: str = "",
) -> Task:
    """The task an evaluation runs (module docstring).

    Args:
        task: the task asked for (``task=``).
        meta: the evaluation dataset's ``meta/factory.json`` (None: no dataset).
        features: the features the evaluated policy reads (None: replay or the planner).
        layout: the layout of the dataset the policy was trained on (``TrainInfo.layout``;
            empty: told by ``features``).

    Raises:
        PolicyError: the policy was trained on another task's dataset than the evaluation's,
            or the dataset or the policy is of another task than the one asked for.
    """
    from factory.dataset.layout import meta_task

    data = None if meta is None else meta_task(meta)
    policy = None if features is None else policy_task(features, layout)
    if data is not None and policy is not None and data is not policy:
        if data.robot_kind == policy.robot_kind:
            raise PolicyError(
                f"the policy was trained on a task={policy.name} dataset, but the evaluation's "
                f"dataset is of task={data.name}: pass eval.dataset=<the dataset it was "
                "trained on>, or evaluate a policy trained on this run's dataset"
            )
        raise PolicyError(
            f"the policy was trained on a {policy.robot_kind} dataset, but the evaluation's "
            f"dataset is {data.robot_kind}: pass eval.dataset=<the dataset it was trained on>, "
            "or evaluate a policy trained on this run's dataset"
        )
    asked = get_task(task)
    default = get_task(DEFAULT_TASK)
    chosen = asked if asked is not default else (data or policy or default)
    for what, other in (("dataset", data), ("policy", policy)):
        if other is not None and other is not chosen:
            if other.robot_kind == chosen.robot_kind:
                raise PolicyError(
                    f"task={task} was asked for, but the {what} is of task={other.name}: "
                    f"evaluate it with task={other.name}, or train a policy on a task={task} "
                    "dataset"
                )
            raise PolicyError(
                f"task={task} is the {chosen.robot_kind} task, but the {what} is of the "
                f"{other.robot_kind} robot: evaluate it with task={other.name}, or train a "
                f"policy on a {chosen.robot_kind} dataset"
            )
    return chosen
