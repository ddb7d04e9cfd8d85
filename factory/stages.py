"""The stage registry: ``name -> "module:function"``, resolved lazily.

A stage function takes a :class:`StageContext` and returns a JSON-ready summary dict. Importing
this module imports no stage.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from factory.context import StageContext
from factory.errors import ConfigError

STAGES: dict[str, str] = {
    "list": "factory.stages:list_stages",
    "generate": "factory.scenes.generate:run",
    "ingest": "factory.scenes.ingest:run",
    "augment": "factory.augment.stage:run",
    "compile": "factory.scenes.build:run_compile",
    "validate": "factory.scenes.validate_stage:run",
    "render": "factory.scenes.build:run_render",
    "export": "factory.scenes.build:run_export",
    "warmup": "factory.demos.warmup:run",
    "demos": "factory.demos.stage:run",
    "dataset": "factory.dataset.stage:run",
    "train": "factory.policy.train_stage:run",
    "eval": "factory.policy.eval_stage:run",
    "report": "factory.report.stage:run",
    "all": "factory.runner:run_all",
}
"""Every stage, in pipeline order."""

CREATES_RUN: frozenset[str] = frozenset({"generate", "ingest", "all"})
"""Stages that may start a new run directory; the others need an existing one."""

DESCRIPTIONS: dict[str, str] = {
    "list": "print the stages and profiles",
    "generate": "scenes from text requests (generate.prompts=[...], generate.task=...)",
    "ingest": "bring scenes into run_dir (scene.json, SAGE layout/folder/zip; default: examples)",
    "augment": "task-consistent variants (augment.levels=[layout,category,configuration])",
    "compile": "compile each scene to MuJoCo: scenes/<id>/model.xml (+ meshes under assets/)",
    "validate": "physics metrics per scene (collision %, stability %), mobile task route check; "
    "validate.repair=true",
    "render": "render top-down and corner views: scenes/<id>/renders/*.png",
    "export": "write scenes back out (export.format=sage: layout JSON + PLY meshes)",
    "warmup": "compile stage=demos' GPU kernels ahead into Warp's kernel cache "
    "(sim.kernel_cache): warmup.json",
    "demos": "recorded robot demonstrations (task=pick_place): episodes/shard-<k>.zarr",
    "dataset": "LeRobot v3 dataset from every demos shard, merged: dataset/merged",
    "train": "a lerobot policy on the merged dataset (train.policy, train.inputs): policy/<name>/",
    "eval": "closed-loop rollouts (eval.policy=<name>|replay|planner): eval/<policy>/results.json",
    "report": "the run's HTML report (scenes, variants, demos, dataset, policies): report.html",
    "all": "run the stages listed in all.stages, in order",
}

PROFILES: dict[str, str] = {
    "small": "CPU only, minutes: CI and tests",
    "default": "one workstation",
    "full": "cluster scale (SLURM arrays)",
}


StageFn = Callable[[StageContext], dict[str, Any]]


def check_stage(name: str) -> str:
    """Returns ``name`` if it is a stage, else raises :class:`ConfigError` listing them."""
    if name not in STAGES:
        raise ConfigError(
            f"unknown stage {name!r}: choose one of {', '.join(STAGES)} "
            "(python -m factory stage=list)"
        )
    return name


def resolve(name: str) -> StageFn:
    """Imports and returns the function of stage ``name``."""
    module, func = STAGES[check_stage(name)].split(":")
    fn: StageFn = getattr(importlib.import_module(module), func)
    return fn


def stage_table() -> str:
    """The stages, profiles and tasks (``task=<name>``), one per line with what it does."""
    from factory.tasks import tasks

    task_list = tasks()
    width = max(map(len, [*STAGES, *PROFILES, *(t.name for t in task_list)]))
    lines = ["stages:"] + [f"  {n:<{width}}  {DESCRIPTIONS[n]}" for n in STAGES]
    lines += ["profiles:"] + [f"  {n:<{width}}  {d}" for n, d in PROFILES.items()]
    lines += ["tasks (task=<name>):"] + [f"  {t.name:<{width}}  {t.description}" for t in task_list]
    return "\n".join(lines)


def list_stages(ctx: StageContext) -> dict[str, Any]:
    """``stage=list``: prints the stages, profiles and tasks."""
    from factory.tasks import task_names

    print(stage_table())
    return {"stages": list(STAGES), "profiles": list(PROFILES), "tasks": task_names()}
