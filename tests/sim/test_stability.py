"""Stability protocol: known-stable and known-unstable fixtures, invalid candidates, and
agreement between backends (threads, MJX, Warp on its CPU device)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from factory.errors import ConfigError
from factory.schema import (
    Euler,
    Physics,
    Placement,
    Room,
    Scene,
    SceneObject,
    Size3,
    Vec3,
    load_scene,
)
from factory.sim.backend_cpu import CpuBackend
from factory.sim.compile import compile_scene
from factory.sim.stability import (
    StabilityProtocol,
    candidates_from_poses,
    check_stability,
    rotation_angle_deg,
)

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")


def _scene(*objects: SceneObject) -> Scene:
    room = Room(id="lab", room_type="lab", position=Vec3(0, 0, 0), dimensions=Size3(3, 3, 2.5))
    return Scene(id="fixture", rooms=[room], objects=list(objects), source="example")


def _box(oid: str, pos: tuple[float, float, float], size: float = 0.2, **kw) -> SceneObject:
    return SceneObject(
        id=oid,
        room_id="lab",
        category="box",
        position=Vec3(*pos),
        dimensions=Size3(size, size, size),
        **kw,
    )


def _table_and_mug() -> Scene:
    table = SceneObject(
        id="table",
        room_id="lab",
        category="table",
        position=Vec3(1.5, 1.5, 0),
        dimensions=Size3(1.0, 0.7, 0.75),
        physics=Physics(mass=25.0),
    )
    mug = SceneObject(
        id="mug",
        room_id="lab",
        category="mug",
        position=Vec3(1.4, 1.5, 0.75),
        dimensions=Size3(0.08, 0.08, 0.1),
        placement=Placement(kind="on_top", support_id="table"),
        physics=Physics(mass=0.33),
    )
    return _scene(table, mug)


def _edge_box() -> Scene:
    """A cube balanced on one edge, tilted 40 degrees: it must topple."""
    a, tilt = 0.2, 40.0
    lift = a / 2 * math.sin(math.radians(tilt)) + 1e-4
    return _scene(_box("box", (1.5, 1.5, lift), a, rotation=Euler(tilt, 0, 0)))


SLOPE_XML = """
<mujoco>
  <option timestep="0.002" integrator="implicitfast"/>
  <worldbody>
    <geom name="ground" type="plane" size="0 0 0.05"/>
    <geom name="ramp" type="box" size="1 1 0.05" pos="0 0 0.5" euler="{deg} 0 0" friction="0.6"/>
    <body name="box" pos="0 0 0" euler="{deg} 0 0">
      <freejoint/>
      <geom type="box" size="0.1 0.1 0.1" mass="1" friction="0.6"/>
    </body>
  </worldbody>
</mujoco>
"""


def _slope_model(deg: float) -> mujoco.MjModel:
    model = mujoco.MjModel.from_xml_string(SLOPE_XML.format(deg=deg))
    # put the box on the ramp's surface: 0.05 (half ramp) + 0.1 (half box) along its normal
    t = math.radians(deg)
    normal = np.array([0.0, -math.sin(t), math.cos(t)])
    adr = model.jnt_qposadr[0]
    model.qpos0[adr : adr + 3] = np.array([0, 0, 0.5]) + normal * 0.1501
    model.qpos0[adr + 3 : adr + 7] = [math.cos(t / 2), math.sin(t / 2), 0, 0]
    return model


STABLE = {
    "box_on_floor": lambda: compile_scene(_scene(_box("box", (1.5, 1.5, 0)))).model,
    "mug_on_table": lambda: compile_scene(_table_and_mug()).model,
    "example_kitchen": lambda: (
        compile_scene(load_scene("factory/data/examples/kitchen_pick_place/scene.json")).model
    ),
    "gentle_slope": lambda: _slope_model(15.0),
}
UNSTABLE = {
    "box_on_edge": lambda: compile_scene(_edge_box()).model,
    "hovering_30cm": lambda: compile_scene(_scene(_box("box", (1.5, 1.5, 0.3)))).model,
    "steep_slope": lambda: _slope_model(40.0),
}


@pytest.mark.parametrize("name", sorted(STABLE))
def test_known_stable(name: str) -> None:
    result = check_stability(STABLE[name]())
    assert result.stable.all(), result.candidate(0)
    assert not result.invalid.any()


@pytest.mark.parametrize("name", sorted(UNSTABLE))
def test_known_unstable(name: str) -> None:
    result = check_stability(UNSTABLE[name](), protocol=StabilityProtocol(resettle=False))
    assert not result.stable.any(), result.candidate(0)
    assert not result.invalid.any()
    assert result.translation.max() > 0.2 or result.rotation_deg.max() > 8.0, result.candidate(0)


def test_resettle_rule_accepts_a_settled_drop() -> None:
    model = UNSTABLE["hovering_30cm"]()
    strict = check_stability(model, protocol=StabilityProtocol(resettle=False))
    lenient = check_stability(model, protocol=StabilityProtocol(resettle=True))
    assert not strict.accepted[0] and not lenient.stable[0]
    assert lenient.resettled[0] and lenient.accepted[0]
    adr = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "box/free")
    z = lenient.settled_qpos[0, model.jnt_qposadr[adr] + 2]
    assert z == pytest.approx(0.0, abs=0.01)  # it came to rest on the floor


def test_bad_candidates_are_flagged_not_fatal() -> None:
    model = compile_scene(_table_and_mug()).model
    poses = np.array(
        [
            [1.4, 1.5, 0.75, 1, 0, 0, 0],  # fine
            [np.nan, 1.5, 0.75, 1, 0, 0, 0],  # NaN pose
            [1.4, 1.5, 0.70, 1, 0, 0, 0],  # 5 cm inside the table
            [1.4, 1.5, 1.05, 1, 0, 0, 0],  # hovering: unstable
        ]
    )
    result = check_stability(model, candidates_from_poses(model, {"mug": poses}))
    assert result.stable.tolist() == [True, False, False, False]
    assert result.invalid.tolist() == [False, True, True, False]
    assert "non-finite" in result.reasons[1]
    assert "starts interpenetrating" in result.reasons[2] and "table" in result.reasons[2]
    assert result.candidate(2)["objects"]["mug"]["penetration_m"] == pytest.approx(0.05, abs=1e-3)


def test_empty_batch_and_wrong_shape() -> None:
    model = STABLE["box_on_floor"]()
    with pytest.raises(ConfigError, match="empty"):
        check_stability(model, np.zeros((0, model.nq)))
    with pytest.raises(ConfigError, match=r"qpos0 must be"):
        check_stability(model, np.zeros((2, model.nq + 1)))
    with pytest.raises(ConfigError, match="not a free body"):
        candidates_from_poses(model, {"ghost": np.zeros((1, 7))})


def _mixed_batch(model: mujoco.MjModel, n: int, seed: int = 0) -> np.ndarray:
    """Mug poses on and around the table: some stable, some falling, some hovering."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform([0.9, 1.1], [2.1, 1.9], size=(n, 2))
    z = rng.choice([0.75, 0.78, 0.95], size=n)
    yaw = rng.uniform(0, math.pi, size=n)
    poses = np.column_stack([xy, z, np.cos(yaw / 2), np.zeros(n), np.zeros(n), np.sin(yaw / 2)])
    return candidates_from_poses(model, {"mug": poses})


def test_threads_give_identical_results() -> None:
    model = compile_scene(_table_and_mug()).model
    q = _mixed_batch(model, 24)
    one = check_stability(model, q, backend=CpuBackend(nthread=1))
    two = check_stability(model, q, backend=CpuBackend(nthread=2))
    assert np.array_equal(one.settled_qpos, two.settled_qpos)
    assert np.array_equal(one.stable, two.stable)
    assert 0 < one.stable.sum() < len(q)  # the batch really mixes verdicts


def test_per_candidate_models() -> None:
    """Different models of one layout (mass variants) run in one batch via set_models."""
    spec_scene = _table_and_mug()
    models = []
    for mass in (0.1, 0.3, 1.0):
        spec_scene.objects[1].physics.mass = mass
        models.append(compile_scene(spec_scene).model)
    result = check_stability(models, np.stack([m.qpos0 for m in models]))
    assert result.stable.all()


@pytest.mark.slow
def test_mjx_agrees_with_cpu() -> None:
    model = compile_scene(_table_and_mug()).model
    q = _mixed_batch(model, 12, seed=1)
    from factory.sim.backend_mjx import MjxBackend

    cpu = check_stability(model, q, backend="cpu")
    mjx = check_stability(model, q, backend=MjxBackend(impl="jax"))
    assert np.array_equal(cpu.stable, mjx.stable)
    assert np.array_equal(cpu.invalid, mjx.invalid)


@pytest.mark.slow
def test_mjx_refuses_large_models() -> None:
    scene = load_scene("factory/data/examples/kitchen_pick_place/scene.json")
    from factory.sim.backend_mjx import MjxBackend

    with pytest.raises(ConfigError, match=r"sim\.backend=warp"):
        check_stability(compile_scene(scene).model, backend=MjxBackend(impl="jax"))


@pytest.mark.slow
def test_warp_on_cpu_device_agrees_with_cpu() -> None:
    model = compile_scene(_table_and_mug()).model
    q = _mixed_batch(model, 6, seed=2)
    cpu = check_stability(model, q, backend="cpu", protocol=StabilityProtocol(resettle=False))
    warp = check_stability(model, q, backend="warp", protocol=StabilityProtocol(resettle=False))
    assert np.array_equal(cpu.stable, warp.stable)
    assert np.allclose(cpu.translation, warp.translation, atol=5e-3)


def _sleep_case(device: str | None) -> None:
    from factory.sim.backend_warp import WarpBackend

    model = compile_scene(_table_and_mug()).model
    protocol = StabilityProtocol(resettle=False)
    nstep = protocol.nstep(model)
    mixed = _mixed_batch(model, 6, seed=2)
    strict = check_stability(
        model, mixed, backend=WarpBackend(device, sleep=False), protocol=protocol
    )
    asleep = check_stability(
        model, mixed, backend=WarpBackend(device, sleep=True), protocol=protocol
    )
    assert np.array_equal(strict.stable, asleep.stable)
    assert np.allclose(strict.translation, asleep.translation, atol=5e-3)
    # A scene at rest falls asleep: the run stops early, with the same final poses.
    rest = np.stack([model.qpos0] * 4)
    engine = WarpBackend(device, sleep=True, graph_steps=25)
    early = check_stability(model, rest, backend=engine, protocol=protocol)
    assert early.stable.all() and engine.steps_run and max(engine.steps_run) < nstep
    full = check_stability(model, rest, backend=WarpBackend(device, sleep=False), protocol=protocol)
    assert np.allclose(early.settled_qpos, full.settled_qpos, atol=2e-3)


@pytest.mark.slow
def test_warp_reuses_device_data_with_the_same_results() -> None:
    """A second call of the same batch shape resets the kept device data (and graph)."""
    from factory.sim.backend_warp import WarpBackend

    model = compile_scene(_table_and_mug()).model
    q = _mixed_batch(model, 4, seed=3)
    engine = WarpBackend("cpu")
    protocol = StabilityProtocol(resettle=False, duration=0.5)  # falling mugs still moving
    first = check_stability(model, q, backend=engine, protocol=protocol)
    assert len(engine._data) == 1
    again = check_stability(model, q, backend=engine, protocol=protocol)
    np.testing.assert_allclose(first.settled_qpos, again.settled_qpos, atol=1e-6)
    assert np.array_equal(first.stable, again.stable)


def test_warp_sleep_is_cuda_only() -> None:
    """MuJoCo Warp's sleeping solver path crashes on Warp's CPU device: off there."""
    from factory.sim.backend_warp import WarpBackend

    assert not WarpBackend("cpu", sleep=True).sleep


@pytest.mark.gpu
def test_warp_sleep_stops_early_with_the_strict_verdicts_on_gpu() -> None:
    """Island sleeping: the verdicts of sleeping off, and an early stop of a scene at rest."""
    _sleep_case("cuda:0")


@pytest.mark.gpu
def test_mjx_on_warp_agrees_with_cpu_and_takes_any_model() -> None:
    """On CUDA, sim.backend=mjx runs MJX's Warp implementation: same verdicts as the CPU
    reference, and a kitchen with dozens of free bodies is accepted."""
    from factory.sim.backend_mjx import MjxBackend

    engine = MjxBackend()
    assert engine.impl == "warp"
    model = compile_scene(_table_and_mug()).model
    q = _mixed_batch(model, 12, seed=1)
    protocol = StabilityProtocol(resettle=False)
    cpu = check_stability(model, q, backend="cpu", protocol=protocol)
    mjx = check_stability(model, q, backend=engine, protocol=protocol)
    assert np.array_equal(cpu.stable, mjx.stable)
    kitchen = compile_scene(load_scene("factory/data/examples/kitchen_pick_place/scene.json"))
    big = check_stability(kitchen.model, backend=engine, protocol=protocol)
    assert len(big.object_ids) > 8 and not big.invalid.any()


def test_rotation_angle() -> None:
    q0 = np.array([1.0, 0, 0, 0])
    q1 = np.array([math.cos(math.radians(10)), 0, 0, math.sin(math.radians(10))])
    assert rotation_angle_deg(q0, q1) == pytest.approx(20.0)
    assert rotation_angle_deg(q1, -q1) == pytest.approx(0.0, abs=1e-5)


def _arena_model(memory_kb: int) -> mujoco.MjModel:
    """One box resting, seven dropping: contacts appear during the run."""
    bodies = "".join(
        f'<body pos="{i * 0.3} 0 {0.05 if i == 0 else 0.5}"><freejoint/>'
        '<geom type="box" size=".1 .1 .05"/></body>'
        for i in range(8)
    )
    xml = (
        f'<mujoco><size memory="{memory_kb}K"/><worldbody>'
        f'<geom type="plane" size="0 0 1"/>{bodies}</worldbody></mujoco>'
    )
    return mujoco.MjModel.from_xml_string(xml)


@pytest.mark.parametrize("memory_kb", [8, 12])
def test_full_buffers_make_candidates_invalid(memory_kb: int) -> None:
    """A MuJoCo error at the start (8 KB) or a full contact buffer mid-run (12 KB) flags the
    candidates invalid, never stable, and does not crash the batch."""
    model = _arena_model(memory_kb)
    result = check_stability(model, np.stack([model.qpos0] * 3))
    assert result.invalid.all() and not result.stable.any() and not result.accepted.any()
    assert all(("MuJoCo error" in r) or ("buffer full" in r) for r in result.reasons)


@pytest.mark.slow
def test_warp_overflow_is_rerun_then_invalid(monkeypatch: pytest.MonkeyPatch) -> None:
    from factory.sim.backend_warp import WarpBackend

    model = compile_scene(_table_and_mug()).model
    q = np.stack([model.qpos0] * 2)
    # 0.5 s (each of the 7 runs of the grown buffers simulates it whole): the contacts are
    # there from the first step, and a mug simulated without them falls 1.2 m in that time
    protocol = StabilityProtocol(duration=0.5)
    monkeypatch.setattr(WarpBackend, "initial_sizes", staticmethod(lambda m, qpos: (1, 4)))
    never = check_stability(model, q, backend=WarpBackend(max_grow=0), protocol=protocol)
    assert never.invalid.all() and "overflowed" in never.reasons[0]
    # 1 -> 64 contacts
    grown = check_stability(model, q, backend=WarpBackend(max_grow=6), protocol=protocol)
    assert not grown.invalid.any() and grown.stable.all()


def test_auto_backend_without_cuda(monkeypatch: pytest.MonkeyPatch) -> None:
    from factory.sim import backend

    monkeypatch.setattr(backend, "cuda_available", lambda: False)
    assert backend.resolve_backend_name("auto") == "cpu"
    with pytest.raises(ConfigError, match=r"sim\.backend"):
        backend.resolve_backend_name("physx")
