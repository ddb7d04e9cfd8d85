"""Configuration variants of a mobile-task scene are route-checked: a variant that puts the can
where the base can reach it only from a part of the room with no way to the desk is rejected
with the route check's reason, batched on the parent's model with the stand-alone verdict."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from living_room import can, desk, living_room

from factory.assets import AssetLibrary
from factory.augment.check import pose_rows
from factory.augment.levels import ConfigurationBatch, configurations
from factory.augment.routes import RouteCells, configuration_routes, route_inputs
from factory.augment.stage import check_route
from factory.nav.route import NO_ROUTE, ROUTE_REASONS
from factory.scenes.brain import AgentConfig, generate_scene
from factory.schema import (
    Physics,
    Placement,
    Scene,
    SceneObject,
    Size3,
    Task,
    Vec3,
    scene_to_json,
)
from factory.sim.compile import compile_scene
from factory.store import RunStore

W, L = 6.0, 5.0
COUNTER = (2.0, 3.2)
"""x extent (m) of a bar counter 0.9 m high that spans the room from wall to wall: nothing
passes it; the part of the room west of it has no way to the desk in the east."""
TOP = 0.9
LIVING = "a living room where the robot moves the coke can from the coffee table to the desk"


def _room() -> Scene:
    x0, x1 = COUNTER
    objects = [
        SceneObject(
            id="counter",
            room_id="living",
            category="counter",
            position=Vec3((x0 + x1) / 2, L / 2, 0.0),
            dimensions=Size3(x1 - x0, L - 0.1, TOP),
            physics=Physics(mass=80.0, static=True),
        ),
        # at the counter's east edge: reachable from the desk's side
        can(Vec3(x1 - 0.2, L / 2, TOP), "counter"),
        desk(5.0, 1.2, "place_support"),
    ]
    return Scene(
        id="bar",
        rooms=[living_room(W, L)],
        objects=objects,
        source="example",
        task=Task(
            kind="mobile_pick_place", instruction="move the can from the counter to the desk"
        ),
    )


def test_configuration_variant_that_blocks_the_route_is_rejected() -> None:
    parent = _room()
    assert check_route(parent, None) is None
    assert route_inputs(parent, ["can"]) == ""
    x0, x1 = COUNTER
    poses = np.array(
        [
            [[x1 - 0.25, 1.5, TOP, 30.0]],  # still by the east edge: the route holds
            [[x0 + 0.2, L / 2, TOP, 0.0]],  # by the west edge: reachable only from the west
            [[1.0, L / 2, 0.0, 0.0]],  # on the floor west of the counter: a new obstacle
        ]
    )
    assert configuration_routes(parent, ["can"], poses, None) == ["", NO_ROUTE, NO_ROUTE]
    # the batched verdict is the variant scene's own route check (compiled alone)
    batch = ConfigurationBatch(parent, ["can"], poses)
    alone = [check_route(batch.variant(i).scene, None) for i in range(3)]
    assert alone == [None, NO_ROUTE, NO_ROUTE]
    # on the counter the can adds no cell to the grid: judged on the parent's grid and
    # lattice; on the floor it does: checked whole
    model = compile_scene(parent).model
    rows = pose_rows(model, model.qpos0, ["can"], poses)
    cells = RouteCells.of(parent, model, ["can"])
    assert cells is not None
    assert cells.check(rows[0]) == ("", "")
    verdict = cells.check(rows[1])
    assert verdict is not None and verdict[0] == NO_ROUTE and "desk" in verdict[1]
    assert cells.check(rows[2]) is None


@pytest.mark.slow
def test_configurations_of_a_generated_room_are_route_checked_as_scenes(tmp_path: Path) -> None:
    """On a generated living room the configuration level re-poses the can (the desk, a
    floor-standing place support, stays), and each variant's batched route verdict is the
    verdict of the variant scene compiled alone."""
    lib = AssetLibrary(tmp_path / "assets")
    parent, _ = generate_scene(LIVING, lib, seed=0, config=AgentConfig(physics_critic=False))
    roles = {o.task_role: o.id for o in parent.objects if o.task_role}
    found = configurations(parent, lib, 3, 6, None)
    assert found.ids == [roles["pick"]] and len(found) == 6
    routes = configuration_routes(parent, found.ids, found.poses, lib.assets_dir)
    alone = [check_route(found.variant(i).scene, lib.assets_dir) or "" for i in range(6)]
    assert routes == alone


def test_variants_that_cannot_change_the_route_are_not_checked() -> None:
    parent = _room()
    parent.objects.append(
        SceneObject(
            id="book",
            room_id="living",
            category="book",
            position=Vec3(COUNTER[0] + 0.3, 1.0, TOP),
            dimensions=Size3(0.15, 0.2, 0.03),
            placement=Placement(kind="on_top", support_id="counter"),
            physics=Physics(mass=0.4),
        )
    )
    why = route_inputs(parent, ["book"])
    assert "book" in why and "can" in why
    poses = np.array([[[COUNTER[0] + 0.3, 3.0, TOP, 0.0]]])
    assert configuration_routes(parent, ["book"], poses, None) == [""]
    parent.task = None
    parent.objects = [o for o in parent.objects if o.task_role != "place_support"]
    assert "mobile task" in route_inputs(parent, ["can"])


@pytest.mark.slow
def test_stage_drops_configuration_variants_that_fail_the_route(cli, tmp_path: Path) -> None:
    """``stage=augment augment.levels=[configuration]`` on a generated living room: every
    kept variant passes the route check, the others are counted by the route check's reason
    (on this room, seed 0, 3 of the 4 variants put the can where the base reaches it only
    from a region with no way to the desk: ``P: no_route`` x3)."""
    import json
    import shutil

    lib = AssetLibrary(tmp_path / "lib")
    parent, _ = generate_scene(LIVING, lib, seed=0, config=AgentConfig(physics_critic=False))
    run = tmp_path / "run"
    (run / "scenes" / parent.id).mkdir(parents=True)
    (run / "scenes" / parent.id / "scene.json").write_text(scene_to_json(parent))
    shutil.copytree(lib.assets_dir, run / "assets")
    out = cli(
        "stage=augment",
        f"run_dir={run}",
        "augment.levels=[configuration]",
        "augment.variants_per_scene=4",
        "augment.render=false",
        "sim.backend=cpu",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    manifest = json.loads((run / "manifest.json").read_text())
    result = manifest["stages"]["augment"]["shards"]["0-of-1"]["result"]
    kept = sorted(p.name for p in (run / "scenes").iterdir() if "__" in p.name)
    assert result["kept"] == len(kept)
    assert result["kept"] + sum(result["dropped"].values()) == 4
    allowed = {f"P: {r}" for r in (*ROUTE_REASONS, "physics", "no distinct valid configuration")}
    assert set(result["dropped"]) <= allowed, result["dropped"]
    store = RunStore(run)
    for name in kept:  # without the check, the variants it drops would be kept here
        assert check_route(store.load_scene(name), run / "assets") is None, name
