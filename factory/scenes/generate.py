"""``stage=generate``: scenes from text, image or task requests, written to the run."""

from __future__ import annotations

import hashlib
import logging
import re
from pathlib import Path
from typing import Any

from factory.assets import AssetLibrary
from factory.scenes.brain import AgentConfig, generate_scene
from factory.scenes.mcp_client import SyncMCPCaller
from factory.scenes.part_read import PartSpec, check_part_request
from factory.scenes.request import parse_request, primary_room_type, request_task
from factory.schema import Scene, check_id

log = logging.getLogger(__name__)


def _read_prompts(cfg: Any) -> list[str]:
    prompts = list(cfg.prompts or [])
    if cfg.prompts_file:
        path = Path(cfg.prompts_file)
        if not path.is_file():
            from factory.errors import ConfigError

            raise ConfigError(f"generate.prompts_file {path} does not exist")
        prompts += [
            ln.strip()
            for ln in path.read_text().splitlines()
            if ln.strip() and not ln.startswith("#")
        ]
    if cfg.task and not prompts:
        prompts = [cfg.task]
    if cfg.image:
        from factory.scenes.vlm import describe_image

        hint = " ".join(prompts)
        prompts = [describe_image(cfg.image, hint, base_url=cfg.vlm_base_url, model=cfg.vlm_model)]
        log.info("image %s described as: %s", cfg.image, prompts[0])
    return prompts


def _library_for(prompt: str, task: str, library: AssetLibrary) -> AssetLibrary:
    """The asset library for a prompt: ``library``, or its articulated copy when the task the
    prompt (or ``generate.task``) asks for needs moving doors and drawers
    (:attr:`factory.tasks.base.Task.articulated_assets`: "open the fridge door"), logged.

    Raises:
        ConfigError: an open or close task names an object that does not open or that the
            prompt's rooms do not hold (:func:`~.part_read.check_part_request`).
    """
    from factory.scenes.brain import task_kind
    from factory.tasks import get_task

    spec = request_task(prompt, task)
    if spec is None:
        return library
    if isinstance(spec, PartSpec):
        check_part_request(spec, parse_request(prompt).room_types)
    kind = task_kind(spec.__dict__)
    if library.articulated or not get_task(kind).articulated_assets:
        return library
    log.info(
        "request %r: task=%s needs doors and drawers that move: its assets are built "
        "articulated (as with assets.articulated=true)",
        prompt,
        kind,
    )
    return library.articulated_copy()


def _generate_with(
    gcfg: Any, prompt: str, library: AssetLibrary, seed: int, agent_cfg: AgentConfig, scene_id: str
) -> tuple[Scene, dict[str, Any]]:
    """One scene with the configured brain and transport."""
    from factory.scenes.tools import ToolSession

    session = ToolSession(
        library, physics=agent_cfg.physics_critic, critic_scope=agent_cfg.critic_scope
    )
    if gcfg.agent == "llm":
        from factory.scenes.agent import AgentError, LLMConfig, run_llm_agent

        llm = LLMConfig(
            base_url=gcfg.llm_base_url,
            model=gcfg.llm_model,
            timeout=gcfg.llm_timeout,
            retries=gcfg.llm_retries,
        )
        try:
            report = run_llm_agent(session, prompt, llm, seed)
            scene = session.scene
            scene.id = check_id(scene_id, "scene id")
            return scene, {**report, "request": prompt, "seed": seed, "objects": len(scene.objects)}
        except AgentError as e:
            if not gcfg.llm_fallback:
                raise
            log.warning(
                "llm agent failed for %r (%s); falling back to the heuristic agent", prompt, e
            )
            scene, report = generate_scene(
                prompt, library, seed, agent_cfg, task=gcfg.task or None, scene_id=scene_id
            )
            return scene, {**report, "fallback_from": "llm", "llm_error": str(e)}
    import contextlib

    mcp_ctx: Any = contextlib.nullcontext(None)
    if gcfg.transport == "mcp":
        from factory.scenes.mcp_server import build_server

        mcp_ctx = SyncMCPCaller(build_server(session))
    with mcp_ctx as caller:
        scene, report = generate_scene(
            prompt,
            library,
            seed,
            agent_cfg,
            task=gcfg.task or None,
            scene_id=scene_id,
            caller=caller,
            session=session,
        )
    if gcfg.vlm_base_url:
        report["vlm_critic"] = _apply_vlm_critic(session, prompt, gcfg)
    return session.scene, report


def _apply_vlm_critic(session: Any, prompt: str, gcfg: Any, limit: int = 8) -> dict[str, Any]:
    """Renders the scene, asks the VLM critic, applies its tool-call suggestions once."""
    import tempfile

    from factory.scenes.agent import AgentError
    from factory.scenes.vlm import vlm_critic

    with tempfile.TemporaryDirectory() as tmp:
        session.out_dir = Path(tmp)
        try:
            views = session.render_views(256, 192)
            verdict = vlm_critic(
                views.get("images", {}), prompt, base_url=gcfg.vlm_base_url, model=gcfg.vlm_model
            )
        except AgentError as e:
            log.warning("VLM critic failed: %s", e)
            return {"error": str(e)}
        finally:
            session.out_dir = None
    applied = []
    for suggestion in verdict.get("suggestions", [])[:limit]:
        call = suggestion.get("call") or {}
        tool, args = call.get("tool"), call.get("args") or {}
        if tool in ("place_objects", "move_object", "remove_object") and isinstance(args, dict):
            try:
                result = getattr(session, tool)(**args)
            except TypeError as e:
                result = {"ok": False, "error": str(e)}
            applied.append({"tool": tool, "args": args, "result": result})
    return {"suggestions": verdict.get("suggestions", []), "applied": applied}


def run(ctx: Any) -> dict[str, Any]:
    """Stage entry point: ``stage=generate``."""
    from factory.context import run_items
    from factory.errors import ConfigError, TaskError
    from factory.scenes.build import compile_one
    from factory.scenes.finish import attempt_seed, finish_scene
    from factory.schema import scene_to_json, validate

    store = ctx.require_store()
    gcfg = ctx.cfg.generate
    prompts = _read_prompts(gcfg)
    if not prompts:
        raise ConfigError(
            "stage=generate needs generate.prompts=[...], generate.prompts_file or generate.task"
        )
    for p in prompts:
        if not p.strip() or len(p) > 2000:
            raise ConfigError(f"prompt {p[:40]!r}... is empty or too long (2000 characters max)")
    jobs = []
    for i, prompt in enumerate(prompts):
        for k in range(gcfg.scenes_per_prompt):
            seed = ctx.cfg.seed + 1000 * i + k
            digest = hashlib.sha1(f"{prompt}|{seed}".encode()).hexdigest()[:8]
            rt = re.sub(r"[^a-z0-9]+", "_", primary_room_type(prompt)).strip("_")
            jobs.append((f"{rt}_{digest}_{k}", prompt, seed))
    mine = ctx.shard.select(jobs)
    by_id = {j[0]: j for j in mine}
    if gcfg.agent not in ("heuristic", "llm"):
        raise ConfigError(f"generate.agent={gcfg.agent!r} must be heuristic or llm")
    if gcfg.transport not in ("direct", "mcp"):
        raise ConfigError(f"generate.transport={gcfg.transport!r} must be direct or mcp")
    if gcfg.task_attempts < 1:
        raise ConfigError(f"generate.task_attempts={gcfg.task_attempts} must be at least 1")
    library = AssetLibrary.from_config(ctx.cfg.assets, store.assets_dir)
    libraries = {p: _library_for(p, gcfg.task or "", library) for p in dict.fromkeys(prompts)}
    agent_cfg = AgentConfig(physics_critic=gcfg.physics_critic, max_objects=gcfg.max_objects)

    def one(scene_id: str) -> str:
        _, prompt, seed = by_id[scene_id]
        if store.scene_json(scene_id).is_file() and not ctx.cfg.force:
            return "skipped"
        from factory.store import atomic_write_json, atomic_write_text

        failed: list[dict[str, Any]] = []
        soft: tuple[float, Any, dict[str, Any]] | None = None  # the best scene that can host
        accepted = False
        for attempt in range(gcfg.task_attempts):
            s = attempt_seed(seed, attempt)
            try:
                scene, report = _generate_with(
                    gcfg, prompt, libraries[prompt], s, agent_cfg, scene_id
                )
            except ValueError as e:
                raise ConfigError(f"prompt {prompt!r}: {e}") from None
            validate(scene)
            scene, checks = finish_scene(scene, store.assets_dir, ctx.cfg, gcfg.final_check)
            report.update(checks)
            verdict = checks.get("task_check")
            if verdict is None or not verdict["reason"]:
                accepted = True
                break
            failed.append({"seed": s, "reason": verdict["reason"], "detail": verdict["detail"]})
            if verdict.get("soft") and (soft is None or verdict.get("gap", 0.0) > soft[0]):
                soft = (float(verdict.get("gap", 0.0)), scene, report)
            log.info(
                "scene %s: attempt %d of %d cannot host its task (%s: %s)",
                scene_id,
                attempt + 1,
                gcfg.task_attempts,
                verdict["reason"],
                verdict["detail"],
            )
        if not accepted:
            if soft is None:
                atomic_write_json(
                    store.report_json(scene_id),
                    {"schema_version": 1, "generate": {"request": prompt, "rejected": failed}},
                )
                raise TaskError(
                    f"scene {scene_id}: none of {len(failed)} attempts can host its task "
                    f"({', '.join(sorted({f['reason'] for f in failed}))}; "
                    f"{store.report_json(scene_id)} lists them): raise generate.task_attempts "
                    "or name a larger support in the request"
                )
            # every attempt can host the task, short of what the critic prefers (a soft
            # verdict: the mobile task's supports closer than it asks): the closest is kept
            _, scene, report = soft
            report["task_check_kept"] = (
                f"no attempt met the task critic ({failed[-1]['reason']}); kept the one "
                "closest to it"
            )
            log.warning("scene %s: %s", scene_id, report["task_check_kept"])
        if failed:
            report["rejected_attempts"] = failed
        atomic_write_json(store.report_json(scene_id), {"schema_version": 1, "generate": report})
        atomic_write_text(store.scene_json(scene_id), scene_to_json(scene))
        compile_one(store, scene_id, ctx.cfg.compile, force=True)
        if gcfg.render:
            from factory.scenes.build import render_one

            render_one(store, scene_id, ctx.cfg.render, force=True)
        return "done"

    result = run_items("generate", list(by_id), one)
    return {**result, "scenes": len(store.scene_ids())}


__all__ = ["run"]
