"""Shared fixtures: SAGE-format packages built from SAGE's documented conventions."""

from __future__ import annotations

import copy
import json
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

# under pytest-xdist each worker gets one core's worth of BLAS, OpenMP and torch threads (set
# before numpy or torch start their pools; subprocesses inherit it)
if os.environ.get("PYTEST_XDIST_WORKER"):
    for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import numpy as np
import pytest
from robot_models import require_robot_models

from factory.sim.gl import configure_gl

configure_gl("auto")  # before any test imports mujoco
# scenes compiled without a run's assets folder cache their floor and wall textures here, not
# in the user's ~/.cache
os.environ.setdefault(
    "FACTORY_TEXTURE_CACHE", os.path.join(tempfile.gettempdir(), "factory-test-textures")
)

REPO = Path(__file__).resolve().parent.parent
EXAMPLE_SCENE = REPO / "factory" / "data" / "examples" / "kitchen_pick_place" / "scene.json"


def _p(x: float, y: float, z: float = 0.0) -> dict[str, float]:
    return {"x": x, "y": y, "z": z}


def _walls(rid: str, x0: float, y0: float, w: float, ln: float, h: float) -> list[dict[str, Any]]:
    pts = [(x0, y0), (x0 + w, y0), (x0 + w, y0 + ln), (x0, y0 + ln)]
    names = ["south", "east", "north", "west"]
    return [
        {
            "id": f"{rid}_{n}",
            "start_point": _p(*pts[i]),
            "end_point": _p(*pts[(i + 1) % 4]),
            "height": h,
            "thickness": 0.1,
            "material": "drywall",
        }
        for i, n in enumerate(names)
    ]


def _obj(
    oid: str,
    room: str,
    typ: str,
    pos: tuple[float, float, float],
    dims: tuple[float, float, float],
    place_id: str,
    yaw: float = 0.0,
    mass: float = 1.0,
    source_id: str | None = None,
) -> dict[str, Any]:
    return {
        "id": oid,
        "room_id": room,
        "type": typ,
        "description": f"a {typ}",
        "position": _p(*pos),
        "rotation": {"x": 0.0, "y": 0.0, "z": yaw},
        "dimensions": {"width": dims[0], "length": dims[1], "height": dims[2]},
        "source": "generation",
        "source_id": source_id or f"{oid}_mesh",
        "place_id": place_id,
        "place_location": "top",
        "place_guidance": "Standard placement for the object",
        "placement_constraints": [],
        "mass": mass,
    }


def sage_layout() -> dict[str, Any]:
    """A two-room SAGE layout exercising every field and placement kind."""
    h = 2.7
    bed = _walls("bedroom", 0.0, 0.0, 4.0, 3.5, h)
    living = _walls("living", 4.0, 0.0, 5.0, 3.5, h)
    bedroom_objects = [
        _obj("bed_0", "bedroom", "bed", (1.5, 1.75, 0.0), (1.6, 2.0, 0.55), "floor", 90.0, 60.0),
        _obj(
            "nightstand_0",
            "bedroom",
            "nightstand",
            (0.35, 0.4, 0.0),
            (0.45, 0.4, 0.5),
            "bedroom",
            0.0,
            8.0,
        ),
        _obj(
            "lamp_0",
            "bedroom",
            "lamp",
            (0.35, 0.4, 0.5),
            (0.15, 0.15, 0.35),
            "nightstand_0",
            0.0,
            0.9,
        ),
        _obj(
            "painting_0",
            "bedroom",
            "painting",
            (2.0, 3.4, 1.4),
            (0.8, 0.03, 0.6),
            "bedroom_north",
            180.0,
            2.0,
        ),
    ]
    bedroom_objects[1]["placement_constraints"] = [{"type": "near", "target": "bed_0"}]
    bedroom_objects[0]["metallic"] = 0.0
    bedroom_objects[0]["roughness"] = 0.8
    bedroom_objects[3]["vlm_notes"] = {"style": "impressionist"}  # a field we do not know
    living_objects = [
        _obj("sofa_0", "living", "sofa", (6.5, 0.6, 0.0), (2.1, 0.9, 0.85), "floor", 0.0, 45.0),
        _obj("tv_0", "living", "tv", (8.9, 1.75, 1.2), (0.08, 1.2, 0.7), "wall", -90.0, 12.0),
        _obj(
            "table_0",
            "living",
            "coffee_table",
            (6.5, 1.9, 0.0),
            (1.1, 0.6, 0.45),
            "floor",
            0.1 + 0.2,
            15.0,
        ),
        _obj("cup_0", "living", "cup", (6.3, 1.9, 0.45), (0.08, 0.08, 0.1), "table_0", 33.3, 0.25),
    ]
    return {
        "id": "sage_two_rooms_001",
        "rooms": [
            {
                "id": "bedroom",
                "room_type": "bedroom",
                "position": _p(0.0, 0.0),
                "dimensions": {"width": 4.0, "length": 3.5, "height": h},
                "walls": bed,
                "doors": [
                    {
                        "id": "door_bed_living",
                        "wall_id": "bedroom_east",
                        "position_on_wall": 0.5,
                        "width": 0.9,
                        "height": 2.1,
                        "door_type": "standard",
                        "opens_inward": True,
                        "opening": False,
                        "door_material": "oak",
                    }
                ],
                "objects": bedroom_objects,
                "windows": [
                    {
                        "id": "window_bed",
                        "wall_id": "bedroom_south",
                        "position_on_wall": 0.4,
                        "width": 1.2,
                        "height": 1.0,
                        "sill_height": 0.9,
                        "window_type": "sliding",
                        "window_material": "aluminium",
                    }
                ],
                "floor_material": "oak hardwood",
                "ceiling_height": h,
            },
            {
                "id": "living",
                "room_type": "living room",
                "position": _p(4.0, 0.0),
                "dimensions": {"width": 5.0, "length": 3.5, "height": h},
                "walls": living,
                "doors": [
                    {
                        "id": "door_living_bed",
                        "wall_id": "living_west",
                        "position_on_wall": 0.5,
                        "width": 0.9,
                        "height": 2.1,
                        "door_type": "standard",
                        "opens_inward": False,
                        "opening": True,
                        "door_material": "standard",
                    }
                ],
                "objects": living_objects,
                "windows": [],
                "floor_material": "carpet",
                "ceiling_height": h,
            },
        ],
        "total_area": 31.5,
        "building_style": "scandinavian",
        "description": "a bedroom next to a living room",
        "created_from_text": "a cosy two-room apartment",
        "policy_analysis": {"task": "pick up the cup", "objects": ["cup_0"]},
        "generator_version": "sage-1.0",  # a top-level field we do not know
    }


def write_box_ply(path: Path, dims: tuple[float, float, float]) -> None:
    """A SAGE-style PLY: a box (bottom at z = 0, centred in x, y) with a texcoord element."""
    from plyfile import PlyData, PlyElement

    w, ln, h = dims
    xs, ys = (-w / 2, w / 2), (-ln / 2, ln / 2)
    verts = [(x, y, z) for z in (0.0, h) for y in ys for x in xs]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    uvs = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    tex_tris = [t for _ in quads for t in ((0, 1, 2), (0, 2, 3))]
    vertex = np.array(verts, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    face = np.empty(
        len(tris), dtype=[("vertex_indices", "i4", (3,)), ("texcoord_indices", "i4", (3,))]
    )
    face["vertex_indices"] = tris
    face["texcoord_indices"] = tex_tris
    texcoord = np.array(uvs, dtype=[("u", "f4"), ("v", "f4")])
    PlyData(
        [
            PlyElement.describe(vertex, "vertex"),
            PlyElement.describe(face, "face"),
            PlyElement.describe(texcoord, "texcoord"),
        ]
    ).write(str(path))


def write_texture(path: Path, rgb: tuple[int, int, int]) -> None:
    from PIL import Image

    im = np.zeros((16, 16, 3), np.uint8)
    im[:] = rgb
    im[::4, :] = 255
    Image.fromarray(im).save(path)


def write_sage_package(folder: Path, layout: dict[str, Any] | None = None) -> Path:
    """Writes a packed SAGE scene (layout + objects/*.ply + textures) into ``folder``."""
    layout = copy.deepcopy(layout or sage_layout())
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "objects").mkdir(exist_ok=True)
    (folder / "materials").mkdir(exist_ok=True)
    for i, room in enumerate(layout["rooms"]):
        for obj in room["objects"]:
            if obj["id"] in ("bed_0", "sofa_0", "cup_0"):
                d = obj["dimensions"]
                sid = obj["source_id"]
                write_box_ply(
                    folder / "objects" / f"{sid}.ply", (d["width"], d["length"], d["height"])
                )
                write_texture(folder / "objects" / f"{sid}_texture.png", (60 + 50 * i, 90, 140))
    (folder / f"{layout['id']}.json").write_text(json.dumps(layout, indent=2))
    return folder


@pytest.fixture
def sage_dict() -> dict[str, Any]:
    return sage_layout()


@pytest.fixture
def sage_package(tmp_path: Path) -> Path:
    return write_sage_package(tmp_path / "sage_pkg")


@pytest.fixture
def example_scene_path() -> Path:
    return EXAMPLE_SCENE


def run_cli(*args: str, env: dict[str, str] | None = None, cwd: Path | None = None):
    """Runs ``python -m factory`` in a subprocess; returns the CompletedProcess."""
    import subprocess

    full_env = {**os.environ, **(env or {})}
    return subprocess.run(
        [sys.executable, "-m", "factory", *args],
        capture_output=True,
        text=True,
        env=full_env,
        cwd=cwd or REPO,
        timeout=600,
    )


@pytest.fixture
def cli():
    """``cli(*args, env=None)`` runs the real command line in a subprocess."""
    return run_cli


# Fixtures that cost minutes, built once per test process: under pytest-xdist (`-n auto --dist
# loadgroup`, the README's test command) every module that uses one runs in the same worker.
SHARED_RUNS = ("small_run", "policy_run")


HEAVY_FIRST = (
    "warp",
    "policy_run",
    "tests/scenes/test_generate.py",
    "small_run",
    "tests/dataset/test_dataset.py",
    "tests/tasks/test_open_close.py",
    "tests/tasks/test_smoke.py",
)
"""The costliest groups, most first (their shares of a 2-core run's work, 2026-11-30: the Warp
modules about a quarter, the policy run's a sixth, scene generation and the small run's a
tenth each, ...): handed out first, so that no worker starts a long group when the other is
nearly done. xdist's own reordering (by number of tests, ``--loadscope-reorder``) is turned off in
:func:`pytest_configure` so that this order holds."""


def pytest_configure(config: pytest.Config) -> None:
    """Keeps the collection's order of test groups for pytest-xdist's scheduler (see
    :data:`HEAVY_FIRST`)."""
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


def _group_by_module(items: list[pytest.Item]) -> None:
    """Gives each module one ``xdist_group`` so that ``--dist loadgroup`` keeps a module (and
    its module- and session-scoped fixtures) in one worker: a module's own ``xdist_group`` mark
    wins (the Warp modules share "warp", so Warp's CPU kernels compile once), then the shared
    run it uses (``SHARED_RUNS``), then the module itself."""
    by_module: dict[str, list[pytest.Item]] = {}
    for item in items:
        by_module.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    for module, module_items in by_module.items():
        marked = [m.args[0] for i in module_items for m in i.iter_markers("xdist_group") if m.args]
        used = {f for i in module_items for f in getattr(i, "fixturenames", ())}
        shared = [name for name in SHARED_RUNS if name in used]
        group = marked[0] if marked else shared[0] if shared else module
        for item in module_items:
            if not any(True for _ in item.iter_markers("xdist_group")):
                item.add_marker(pytest.mark.xdist_group(group))

    def rank(item: pytest.Item) -> int:
        group = next((m.args[0] for m in item.iter_markers("xdist_group") if m.args), "")
        return HEAVY_FIRST.index(group) if group in HEAVY_FIRST else len(HEAVY_FIRST)

    items.sort(key=rank)  # stable: each group's own order is kept


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Groups tests for pytest-xdist; tests marked ``gpu`` run only where a CUDA device is
    present. First among the hooks: xdist's own reads the groups into the test ids (for
    ``--dist loadgroup``) in its hook, so they must be there before it runs."""
    _group_by_module(items)
    if os.path.exists("/dev/nvidiactl"):
        return
    skip = pytest.mark.skip(reason="needs a CUDA device (run on the GPU machine)")
    for item in items:
        if "gpu" in item.keywords:
            item.add_marker(skip)


def _make_kitchen(assets: Path, seed: int = 3, scene_id: str | None = None) -> Any:
    """A kitchen with a dining table, a mug (pick), a bowl (target) and a plate on it."""
    from factory.assets import AssetLibrary
    from factory.scenes.tools import ToolSession

    session = ToolSession(AssetLibrary(assets), physics=False)
    assert session.init_scene("a kitchen", seed=seed)["ok"]
    table = session.place_objects("dining table", placement="floor", rule="center")
    assert table["ok"], table
    tid = table["placed"][0]
    for text, role in (("bowl", "place_target"), ("mug", "pick")):
        res = session.place_objects(text, placement="on_top", target=tid, task_role=role)
        assert res["ok"], res
    session.place_objects("plate", placement="on_top", target=tid)
    scene = session.scene
    scene.task = None
    if scene_id is not None:
        scene.id = scene_id
    return scene


@pytest.fixture(scope="session")
def _robosuite_imports(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("robosuite-imports")


@pytest.fixture(autouse=True)
def _import_robosuite_once(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch):
    """Each new assets folder imports robosuite's textured meshes (about 10 s, mostly CoACD's
    convex decompositions): in this process the import runs once and later assets folders get
    a copy of its files (the same files: the import is deterministic, which
    tests/assets/test_real_meshes.py checks with the real import, left alone there).
    Subprocesses (the command line) import for themselves."""
    if request.node.path.name == "test_real_meshes.py":
        return
    from factory.assets import packaged

    imports = request.getfixturevalue("_robosuite_imports")
    write = packaged._write_robosuite

    def write_once(folder: Path, src: Any, key: str) -> None:
        done = imports / f"{src.version}-{key}"
        if (done / "metadata.json").is_file():
            shutil.copytree(done, folder, dirs_exist_ok=True)
            return
        write(folder, src, key)
        shutil.copytree(folder, imports / f".{done.name}")
        os.rename(imports / f".{done.name}", done)

    monkeypatch.setattr(packaged, "_write_robosuite", write_once)


@pytest.fixture(scope="session")
def make_kitchen():
    """``make_kitchen(assets_dir, seed=3, scene_id=None) -> Scene`` (procedural assets)."""
    return _make_kitchen


@dataclass
class CliRun:
    """A run made through the command line: its directory and the finished process."""

    run_dir: Path
    out: Any


@pytest.fixture(scope="session")
def small_run(tmp_path_factory: pytest.TempPathFactory) -> CliRun:
    """The README's main job, once per session: ``stage=all profile=small`` (a generated kitchen,
    validated, two recorded demos, the LeRobot dataset, the report; a few minutes on CPU).

    Shared by every test that asks for it: read it, or copy it before changing anything.
    """
    require_robot_models()
    pytest.importorskip("lerobot")
    run = tmp_path_factory.mktemp("small") / "run"
    out = run_cli("stage=all", "profile=small", f"run_dir={run}", env={"OMP_NUM_THREADS": "1"})
    assert out.returncode == 0, out.stderr[-3000:]
    return CliRun(run, out)
