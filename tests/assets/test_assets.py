"""Asset library: every category x 5 seeds, the resolver, the cache, physical sanity in
MuJoCo, and the mesh-library and text-to-3D backends against real files and a real server."""

from __future__ import annotations

import http.server
import json
import multiprocessing as mp
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from factory.assets import (
    CATEGORIES,
    AssetError,
    AssetLibrary,
    AssetSpec,
    TrellisConfig,
    generate,
    resolve,
)
from factory.assets.cache import cached
from factory.assets.geometry import MAX_HULL_VERTICES
from factory.schema import AssetRef, Physics, Placement, Room, Scene, SceneObject, Size3, Vec3
from factory.sim.compile import compile_scene
from factory.sim.stability import FreeBodies, StabilityProtocol, check_stability

SEEDS = (0, 2, 4)  # three of the five seeds the mass ranges were calibrated on


@pytest.mark.parametrize("category", sorted(CATEGORIES))
def test_every_category_every_seed(category: str) -> None:
    cat = CATEGORIES[category]
    lo, hi = cat.mass
    for seed in SEEDS:
        request = tuple(v * (0.9 + 0.05 * seed) for v in cat.dims)
        gen = generate(AssetSpec(category, dims=request, seed=seed))
        visual = gen.visual
        assert visual.is_watertight, f"{category} seed {seed}: visual mesh not watertight"
        assert np.allclose(visual.extents, request, rtol=0.02), (visual.extents, request)
        for part in gen.shape.parts:
            for hull in part.collision:
                assert hull.is_convex and len(hull.vertices) <= MAX_HULL_VERTICES
                assert hull.volume > 0
        typical = generate(AssetSpec(category, seed=seed))
        assert lo <= typical.mass <= hi, f"{category}: {typical.mass:.3f} kg not in {lo}-{hi}"


def test_enough_categories_for_rooms_and_manipulation() -> None:
    assert len(CATEGORIES) >= 300
    for needed in (
        "mug",
        "cup",
        "bowl",
        "plate",
        "bottle",
        "can",
        "jar",
        "apple",
        "orange",
        "banana",
        "book",
        "cardboard_box",
        "vase",
        "pen",
        "remote",
        "laptop",
    ):
        assert needed in CATEGORIES
    rooms = {r for c in CATEGORIES.values() for r in c.rooms}
    for room in (
        "bedroom",
        "kitchen",
        "living room",
        "dining room",
        "bathroom",
        "office",
        "children's room",
        "gym",
        "meeting room",
        "classroom",
        "restroom",
        "game den",
    ):
        assert room in rooms, room


def test_catalogue_data_rejects_a_bad_entry_naming_the_field() -> None:
    from factory.assets.catalog import CatalogError, build_category
    from factory.errors import ConfigError

    good = {"template": {"kind": "table"}, "dims": [1, 1, 1], "materials": ["oak", "oak"]}
    good["mass"] = [1, 9]
    assert build_category("t", good).dims == (1.0, 1.0, 1.0)
    bad = [
        ({"template": {"kind": "tabel"}}, r"'t', field 'template.kind'.*table"),
        ({"template": {"kind": "vessel", "r_ratio": 1}}, r"field 'template.wall': missing"),
        (
            {"template": {"kind": "block", "fil": 1}},
            r"field 'template.fil'.*valid parameters: fill",
        ),
        ({"materials": ["oak", "cheese"]}, r"field 'materials'.*'cheese'.*walnut"),
        ({"placement": "ceiling"}, r"field 'placement'.*floor, wall, on_top"),
        ({"group": "toys"}, r"field 'group'.*manipulable"),
        ({"mass": [9, 1]}, r"field 'mass'"),
        ({"fixed": "yes"}, r"field 'fixed': expected true or false"),
        ({"dims": [1, 1]}, r"field 'dims'.*3 numbers"),
        ({"colour": [0, 0, 0, 1]}, r"field 'colour': unknown field.*colors"),
        (
            {"template": {"kind": "parts", "parts": [{"box": [0, 0, 0, 1, 1, 1], "axis": "w"}]}},
            r"field 'template.parts\[0\].axis'.*valid keys",
        ),
        (
            {"template": {"kind": "parts", "parts": [{"cyl": [0, 0, 0, 1, 1, 1], "axis": "w"}]}},
            r"field 'template.parts\[0\].axis'.*x, y, z",
        ),
    ]
    for change, message in bad:
        with pytest.raises(CatalogError, match=message) as err:
            build_category("t", good | change)
        assert isinstance(err.value, ConfigError)
    with pytest.raises(CatalogError, match=r"field 'rooms'.*'moon base' is not one of.*kitchen"):
        build_category("t", good | {"rooms": ["moon base"]}, ("kitchen", "office"))


def test_concave_objects_are_concave() -> None:
    bowl = generate(AssetSpec("bowl", dims=(0.2, 0.2, 0.08)))
    assert len(bowl.shape.containers) == 1 and len(bowl.shape.parts[0].collision) > 10
    hull_volume = bowl.visual.convex_hull.volume
    assert sum(p.volume for p in bowl.shape.parts) < 0.5 * hull_volume  # really hollow
    shelf = generate(AssetSpec("bookshelf", seed=1))
    boards = [s for s in shelf.shape.supports if "board" in s.name]
    assert len(boards) >= 3 and len(shelf.shape.containers) == len(boards) + 1


RESOLVE = [
    ("small blue ceramic bowl", "bowl", {"material": "ceramic", "smaller": True}),
    ("a rusty metal stool", "stool", {"material": "rusty metal"}),
    ("king-size bed", "bed", {"width": 1.93}),
    ("mid-century armchair", "armchair", {"style": "mid-century"}),
    ("cyberpunk sofa", "sofa", {"style": "cyberpunk"}),
    ("fairy-tale princess wardrobe", "wardrobe", {"style": "fairy-tale"}),
    ("a tall oak bookcase", "bookshelf", {"taller": True, "material": "oak"}),
    ("couch", "sofa", {}),
    ("fridge", "refrigerator", {}),
    ("a wooden chair next to the table", "chair", {}),
]


@pytest.mark.parametrize(("text", "category", "expect"), RESOLVE, ids=[r[0] for r in RESOLVE])
def test_resolver(text: str, category: str, expect: dict) -> None:
    res = resolve(text)
    assert res.spec.category == category and not res.approximated and res.confidence == 1.0
    typical = CATEGORIES[category].dims
    if "material" in expect:
        assert res.spec.materials is not None and res.spec.materials[0] == expect["material"]
    if expect.get("smaller"):
        assert res.spec.dims is not None and res.spec.dims[0] < typical[0]
    if expect.get("taller"):
        assert res.spec.dims is not None and res.spec.dims[2] > typical[2]
    if "width" in expect:
        assert res.spec.dims is not None and res.spec.dims[0] == pytest.approx(expect["width"])
    if "style" in expect:
        assert res.spec.style == expect["style"] and res.spec.colors is not None


def test_resolver_approximates_and_says_so() -> None:
    typo = resolve("a refridgerator")
    assert typo.spec.category == "refrigerator" and typo.approximated and typo.confidence < 1
    nonsense = resolve("xyzzy plugh")
    assert nonsense.approximated and nonsense.confidence <= 0.4
    assert "approximated" in nonsense.notes[0]
    with pytest.raises(AssetError, match="could not recognise"):
        resolve("xyzzy plugh", allow_fallback=False)
    with pytest.raises(AssetError, match="empty"):
        resolve("   ")


def test_resolver_reads_every_catalogue_phrase_exactly() -> None:
    from factory.assets.resolver import _VOCAB

    wrong = {p: r.spec.category for p in _VOCAB if (r := resolve(p)).spec.category != _VOCAB[p]}
    assert not wrong
    assert all(not resolve(p).approximated for p in _VOCAB)


@pytest.mark.parametrize(
    ("text", "category"),
    [
        ("microwve", "microwave"),
        ("a blu mugg", "mug"),
        ("bokshelf", "bookshelf"),
        ("waana", "banana"),
    ],
)
def test_resolver_fuzzy_similarity_is_rapidfuzz_ratio(text: str, category: str) -> None:
    from rapidfuzz import fuzz

    res = resolve(text)
    word = text.split()[-1]
    assert res.spec.category == category and res.approximated
    assert res.confidence == round(fuzz.ratio(word, res.matched) / 100, 2)


@pytest.mark.parametrize("dims", [(-1, 0.2, 0.2), (0.1, 0.0, 0.1), (50, 1, 1), (1, 1)])
def test_bad_dimensions_write_nothing(tmp_path: Path, dims: tuple) -> None:
    lib = AssetLibrary(tmp_path)
    with pytest.raises(AssetError, match="dimensions"):
        lib.from_text("a mug", dims=dims)
    assert (
        not any(p.name.startswith("proc-") for p in tmp_path.iterdir())
        if tmp_path.exists()
        else True
    )


def test_cache_same_request_same_asset(tmp_path: Path) -> None:
    lib = AssetLibrary(tmp_path)
    a, _ = lib.from_text("small blue ceramic bowl", seed=3)
    b, _ = lib.from_text("small blue ceramic bowl", seed=3)
    c, _ = lib.from_text("small blue ceramic bowl", seed=4)
    assert a.asset_id == b.asset_id != c.asset_id
    assert a.license == "CC0-1.0" and a.provenance["generator"].endswith("/bowl")
    (tmp_path / a.asset_id / "meta.json").write_text("{broken")
    again, _ = lib.from_text("small blue ceramic bowl", seed=3)  # rebuilt, not trusted
    assert again.asset_id == a.asset_id and cached(tmp_path, a.asset_id) is not None


def _build(folder: str, barrier) -> str:  # runs in a child process
    barrier.wait()
    return AssetLibrary(Path(folder)).get(AssetSpec("bookshelf", seed=7)).asset_id


def test_two_processes_leave_one_intact_copy(tmp_path: Path) -> None:
    ctx = mp.get_context("spawn")
    barrier = ctx.Manager().Barrier(2)
    with ctx.Pool(2) as pool:
        ids = pool.starmap(_build, [(str(tmp_path), barrier)] * 2)
    assert ids[0] == ids[1]
    # no temp folders or files left: the asset and the shared texture cache
    assert sorted(p.name for p in tmp_path.iterdir()) == [ids[0], "textures"]
    assert all(p.suffix == ".png" for p in (tmp_path / "textures").iterdir())
    assert cached(tmp_path, ids[0]) is not None


# ---- physical sanity in MuJoCo


def _scene_with(lib: AssetLibrary, items: list[tuple]) -> Scene:
    room = Room(id="r", room_type="kitchen", position=Vec3(0, 0, 0), dimensions=Size3(3, 3, 2.5))
    objs = []
    for oid, text, dims, pos, support, yaw in items:
        meta, res = lib.from_text(text, dims=dims)
        objs.append(
            SceneObject(
                id=oid,
                room_id="r",
                category=res.spec.category,
                position=Vec3(*pos),
                dimensions=Size3(*meta.extents),
                rotation=__import__("factory.schema", fromlist=["Euler"]).Euler(0, 0, yaw),
                placement=Placement("on_top", support) if support else Placement(),
                asset=AssetRef("procedural", meta.asset_id),
                physics=Physics(mass=meta.mass or 1.0, friction=meta.friction or 0.6),
            )
        )
    return Scene(id="sanity", rooms=[room], objects=objs, source="example")


def _settle(scene: Scene, assets: Path) -> tuple[FreeBodies, np.ndarray, object]:
    model = compile_scene(scene, assets).model
    result = check_stability(model, protocol=StabilityProtocol(resettle=False))
    return FreeBodies.of(model), result.settled_qpos[0], result


def _pos(free: FreeBodies, q: np.ndarray, name: str) -> np.ndarray:
    a = free.qposadr[free.index(name)]
    return q[a : a + 3]


def test_mug_dropped_into_bowl_stays_inside(tmp_path: Path) -> None:
    lib = AssetLibrary(tmp_path)
    bowl_meta, _ = lib.from_text("ceramic bowl", dims=(0.22, 0.22, 0.09))
    inner_floor = bowl_meta.containers[0]["lo"][2]
    scene = _scene_with(
        lib,
        [
            ("table", "oak dining table", None, (1.5, 1.5, 0.0), None, 0.0),
        ],
    )
    table_h = scene.objects[0].dimensions.height
    scene = _scene_with(
        lib,
        [
            ("table", "oak dining table", None, (1.5, 1.5, 0.0), None, 0.0),
            ("bowl", "ceramic bowl", (0.22, 0.22, 0.09), (1.5, 1.5, table_h), "table", 0.0),
            ("mug", "red mug", None, (1.49, 1.5, table_h + inner_floor + 0.05), "bowl", 30.0),
        ],
    )
    free, q, _ = _settle(scene, tmp_path)
    mug, bowl = _pos(free, q, "mug"), _pos(free, q, "bowl")
    assert np.linalg.norm(mug[:2] - bowl[:2]) < 0.11 - 0.04  # inside the rim
    assert mug[2] == pytest.approx(bowl[2] + inner_floor, abs=0.01)  # resting on its floor
    assert bowl[2] == pytest.approx(table_h, abs=0.005)


def test_stack_of_three_books_stays_up(tmp_path: Path) -> None:
    lib = AssetLibrary(tmp_path)
    h = 0.035
    scene = _scene_with(
        lib,
        [
            ("book_0", "red book", (0.16, 0.24, h), (1.5, 1.5, 0.0), None, 0.0),
            ("book_1", "blue book", (0.15, 0.23, h), (1.51, 1.5, h), "book_0", 10.0),
            ("book_2", "green book", (0.17, 0.22, h), (1.5, 1.49, 2 * h), "book_1", -8.0),
        ],
    )
    _, _, result = _settle(scene, tmp_path)
    assert result.stable[0], result.candidate(0)


def test_plate_on_a_shelf_board_stays_on_it(tmp_path: Path) -> None:
    lib = AssetLibrary(tmp_path)
    shelf, _ = lib.from_text("oak bookshelf", dims=(0.9, 0.32, 1.8))
    board = next(s for s in shelf.supports if "board" in s["name"])
    x0, y0, x1, y1 = board["rect"]
    scene = _scene_with(
        lib,
        [
            ("shelf", "oak bookshelf", (0.9, 0.32, 1.8), (1.5, 1.5, 0.0), None, 0.0),
            (
                "plate",
                "white plate",
                (0.24, 0.24, 0.025),
                (1.5 + (x0 + x1) / 2, 1.5 + (y0 + y1) / 2, board["z"]),
                "shelf",
                0.0,
            ),
        ],
    )
    free, q, result = _settle(scene, tmp_path)
    assert result.stable[0], result.candidate(0)
    assert _pos(free, q, "plate")[2] == pytest.approx(board["z"], abs=0.01)


# ---- mesh library (real files, CoACD)


def _u_shape() -> trimesh.Trimesh:
    """A concave, watertight U-shaped trough (a U polygon in x-z extruded 0.1 m along y)."""
    outline = [
        (-0.15, 0),
        (0.15, 0),
        (0.15, 0.2),
        (0.13, 0.2),
        (0.13, 0.02),
        (-0.13, 0.02),
        (-0.13, 0.2),
        (-0.15, 0.2),
    ]
    tris = [(0, 1, 4), (1, 2, 4), (2, 3, 4), (0, 4, 5), (0, 5, 6), (0, 6, 7)]
    n = len(outline)
    verts = [(x, y, z) for y in (0.0, 0.1) for x, z in outline]
    faces = [(a, b, c) for a, b, c in tris] + [(c + n, b + n, a + n) for a, b, c in tris]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j + n, j), (i, i + n, j + n)]
    mesh = trimesh.Trimesh(verts, faces, process=True)
    trimesh.repair.fix_normals(mesh)
    assert mesh.is_watertight and not mesh.is_convex
    return mesh


def _library(tmp_path: Path) -> Path:
    lib = tmp_path / "meshes"
    lib.mkdir()
    trimesh.creation.box((0.3, 0.2, 0.1)).export(lib / "crate.obj")
    _u_shape().export(lib / "trough.ply")
    trimesh.creation.icosphere(radius=0.1).export(lib / "ball.stl")
    (lib / "notamesh.obj").write_text("hello world\n")
    (lib / "empty.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 0\nelement face 0\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    (lib / "metadata.json").write_text(
        json.dumps(
            [
                {
                    "file": "crate.obj",
                    "category": "crate",
                    "tags": ["crate", "box"],
                    "license": "CC0-1.0",
                },
                {
                    "file": "trough.ply",
                    "category": "basket",
                    "tags": ["trough", "u"],
                    "license": "CC-BY-4.0",
                },
                {"file": "ball.stl", "category": "ball", "tags": ["ball"], "license": "CC0-1.0"},
                {"file": "notamesh.obj", "category": "vase", "tags": ["broken"], "license": "x"},
                {"file": "empty.ply", "category": "jar", "tags": ["empty"], "license": "x"},
            ]
        )
    )
    return lib


def test_mesh_library_backend(tmp_path: Path) -> None:
    lib = AssetLibrary(tmp_path / "assets", "mesh_library", _library(tmp_path), fallback=False)
    crate, _ = lib.from_text("a wooden crate", dims=(0.5, 0.4, 0.3))
    assert np.allclose(crate.extents, (0.5, 0.4, 0.3), rtol=0.02)
    assert crate.license == "CC0-1.0" and crate.provenance["source_file"] == "crate.obj"
    trough, _ = lib.from_text("a u trough basket", dims=(0.3, 0.1, 0.2))
    assert len(trough.collision) >= 2  # the concave mesh was decomposed by CoACD
    folder = tmp_path / "assets" / trough.asset_id
    for name in trough.collision:
        hull = trimesh.load(folder / name, force="mesh")
        assert hull.is_convex and len(hull.vertices) <= MAX_HULL_VERTICES
    with pytest.raises(AssetError, match=r"not a readable mesh|no faces"):
        lib.from_text("a broken vase")
    with pytest.raises(AssetError, match=r"no faces|not a readable mesh"):
        lib.from_text("an empty jar")
    assert not any(p.name.startswith(".") for p in (tmp_path / "assets").iterdir())


# ---- text-to-3D server (real HTTP)


class _Server(http.server.BaseHTTPRequestHandler):
    mode = "ok"
    calls = 0

    def do_POST(self) -> None:
        type(self).calls += 1
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        if self.mode == "slow":
            time.sleep(1.0)
        if self.mode == "garbage":
            data, ctype = b"<html>oops</html>", "text/html"
        else:
            mesh = trimesh.creation.cylinder(radius=0.05, height=0.1 + 0.01 * body["seed"])
            data, ctype = mesh.export(file_type="ply"), "application/ply"
        self.send_response(200)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def trellis_server():
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Server)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.shutdown()


def test_trellis_backend(tmp_path: Path, trellis_server) -> None:
    url = f"http://127.0.0.1:{trellis_server.server_address[1]}/generate"
    _Server.mode, _Server.calls = "ok", 0
    cfg = TrellisConfig(url=url, timeout=5, retries=1, backoff=0.01)
    lib = AssetLibrary(tmp_path, "trellis", trellis=cfg, fallback=False)
    can, _ = lib.from_text("a soda can", dims=(0.066, 0.066, 0.12))
    assert can.backend == "trellis" and np.allclose(can.extents, (0.066, 0.066, 0.12), rtol=0.02)
    assert can.provenance["server"] == url and can.collision
    lib.from_text("a soda can", dims=(0.066, 0.066, 0.12))
    assert _Server.calls == 1  # second request served from the cache
    _Server.mode = "garbage"
    with pytest.raises(AssetError, match="failed after 2 attempt"):
        lib.from_text("a glass bottle")
    fallback = AssetLibrary(tmp_path, "trellis", trellis=cfg, fallback=True)
    meta, _ = fallback.from_text("a glass bottle")
    assert meta.backend == "procedural" and meta.provenance["fallback_from"] == "trellis"
    _Server.mode = "slow"
    slow = AssetLibrary(
        tmp_path, "trellis", trellis=TrellisConfig(url=url, timeout=0.2, retries=0), fallback=False
    )
    with pytest.raises(AssetError, match="failed after 1 attempt"):
        slow.from_text("a jar")
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())


def test_assets_cli(tmp_path: Path) -> None:
    out = tmp_path / "bowl.png"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "factory.assets",
            "small blue ceramic bowl",
            "--out",
            str(out),
            "--size",
            "128",
            "--assets",
            str(tmp_path / "a"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["category"] == "bowl" and out.stat().st_size > 1000
    listing = subprocess.run(
        [sys.executable, "-m", "factory.assets", "--list"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert listing.returncode == 0 and f"{len(CATEGORIES)} categories" in listing.stdout
    rooms = subprocess.run(
        [sys.executable, "-m", "factory.assets", "--rooms"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert rooms.returncode == 0, rooms.stderr
    count = int(rooms.stdout.strip().splitlines()[-1].split()[0])
    assert count >= 50 and "japanese room" in rooms.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "factory.assets", "mug", "--dims", "0", "1", "1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode == 2 and "dimensions" in bad.stderr


def test_library_from_config(tmp_path: Path) -> None:
    from factory.config import AssetsConfig

    lib = AssetLibrary.from_config(AssetsConfig(), tmp_path)
    assert lib.backend == "procedural"
    with pytest.raises(AssetError, match="library_dir"):
        AssetLibrary.from_config(AssetsConfig(backend="mesh_library"), tmp_path)
    with pytest.raises(AssetError, match="not one of"):
        AssetLibrary.from_config(AssetsConfig(backend="dreamfusion"), tmp_path)


def test_docs_list_every_category() -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "ASSETS.md").read_text()
    missing = [c for c in CATEGORIES if f"| {c} |" not in doc]
    assert not missing, f"regenerate docs/ASSETS.md: missing {missing}"
