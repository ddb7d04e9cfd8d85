"""Textured real meshes shipped, with a licence, by packages already installed.

robosuite (MIT) ships textured object meshes: a can, a bottle, a milk carton, a cereal box,
a slice of bread and a lemon (``robosuite/models/assets/objects``: an MJCF file per object
naming its mesh, scale and texture; the OBJ files carry texture coordinates).
:func:`import_robosuite` turns them into a mesh library folder (``metadata.json`` with
``schema_version``; per object a textured OBJ, its texture and convex hulls of <= 64
vertices; the licence text), which both the ``mesh_library`` backend
(``assets.library_dir=<folder>``) and the procedural backend (``assets.real_meshes=true``, the
default) read: "a coke can" is then robosuite's can with its Coca-Cola label instead of a grey
cylinder. Offline: nothing is downloaded; without robosuite the procedural assets are used.

Sizes are robosuite's (metres, its ``<mesh scale>`` applied): the can is 5 cm across and 8 cm
tall. Masses are volume x an effective density that counts the contents (a full can, a carton
of milk, a box of cereal), so each lies in its category's documented range.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from factory.assets.procedural import AssetError, AssetSpec

log = logging.getLogger(__name__)

PACKAGED_SCHEMA_VERSION = 1
"""``schema_version`` of an imported library's ``metadata.json``."""
IMPORTER_VERSION = 2
"""Bumped when the import changes its output (part of the library folder's key)."""
PACKAGED_DIR = "packaged"
"""Imported libraries inside a run's assets folder (``assets/packaged/<package>-<key>/``)."""


@dataclass(frozen=True)
class PackagedObject:
    """One textured object of a package.

    Attributes:
        name: entry name (unique in the library), e.g. ``coke_can``.
        xml: the package's MJCF file of the object (its ``<mesh scale>`` sizes the mesh).
        obj: the OBJ with texture coordinates (same geometry as the MJCF's mesh).
        texture: the texture image.
        category: the catalogue category it stands for.
        phrases: words of a request that name this object (longest match wins; e.g. "tin can"
            is a can but not this one).
        density: effective density (kg/m³) of the closed volume, contents included.
        material: physics material (friction) and the materials a request may name.
        accepts: material words a request may name and still get this mesh.
        tile_u: the texture repeated this many times across u (the label twice round the can,
            as on a real one; 1: as shipped).
        flat_top: the object has a flat top that can hold things.
        finish: MuJoCo material finish (``specular``, ``shininess``, ``reflectance``).
    """

    name: str
    xml: str
    obj: str
    texture: str
    category: str
    phrases: tuple[str, ...]
    density: float
    material: str
    accepts: tuple[str, ...] = ()
    tile_u: int = 1
    flat_top: bool = False
    finish: tuple[float, float, float] = (0.3, 0.3, 0.0)


ROBOSUITE: tuple[PackagedObject, ...] = (
    PackagedObject(
        "coke_can",
        "can.xml",
        "meshes/can.obj",
        "../textures/can.png",
        "can",
        ("can", "soda can", "coke can", "cola can", "coke", "cola", "coca cola", "coca-cola"),
        950.0,
        "aluminium",
        accepts=("aluminium", "metal"),
        tile_u=2,
        flat_top=True,
        finish=(0.6, 0.6, 0.05),
    ),
    PackagedObject(
        "soda_can",
        "can.xml",
        "meshes/can.obj",
        "../textures/soda.png",
        "can",
        ("can", "soda can", "soda", "diet soda", "diet soda can", "drink can"),
        950.0,
        "aluminium",
        accepts=("aluminium", "metal"),
        flat_top=True,
        finish=(0.6, 0.6, 0.05),
    ),
    PackagedObject(
        "bottle",
        "bottle.xml",
        "meshes/bottle.obj",
        "../textures/glass.png",
        "bottle",
        ("bottle", "water bottle", "glass bottle", "green bottle"),
        1200.0,
        "glass",
        accepts=("glass",),
        finish=(0.8, 0.8, 0.05),
    ),
    PackagedObject(
        "milk",
        "milk.xml",
        "meshes/milk.obj",
        "../textures/ceramic.png",
        "milk_carton",
        ("milk", "milk carton", "carton of milk", "milk box"),
        1000.0,
        "cardboard",
        accepts=("cardboard", "paper"),
    ),
    PackagedObject(
        "cereal",
        "cereal.xml",
        "meshes/cereal.obj",
        "../textures/cereal.png",
        "cereal_box",
        ("cereal", "cereal box", "box of cereal", "cereals"),
        200.0,
        "cardboard",
        accepts=("cardboard", "paper"),
        flat_top=True,
    ),
    PackagedObject(
        "bread",
        "bread.xml",
        "meshes/bread.obj",
        "../textures/bread.png",
        "bread",
        ("bread", "toast", "slice of bread", "bread slice"),
        280.0,
        "organic",
        accepts=("organic",),
    ),
    PackagedObject(
        "lemon",
        "lemon.xml",
        "meshes/lemon.obj",
        "../textures/lemon.png",
        "lemon",
        ("lemon",),
        1000.0,
        "organic",
        accepts=("organic",),
    ),
)
"""robosuite 1.5's textured objects (``plate-with-hole``, the nuts and the door are not
textured objects and are left out)."""


@dataclass
class PackagedLibrary:
    """An imported mesh library folder.

    Attributes:
        folder: the library folder (``metadata.json`` and one sub-folder per entry).
        entries: the ``metadata.json`` entries (``file``, ``texture``, ``collision``, ...).
        package: the source package.
        version: its version.
    """

    folder: Path
    entries: list[dict[str, Any]]
    package: str
    version: str


# ---- robosuite


@dataclass(frozen=True)
class PackageSource:
    """Where an installed package's files are: its folder, version and licence file."""

    root: Path
    version: str
    license_file: Path


def robosuite_source() -> PackageSource | None:
    """robosuite's installed folder, version and LICENSE, or ``None`` if it is not installed
    (found without importing it: robosuite's import is slow and loud)."""
    import importlib.metadata
    import importlib.util

    try:
        spec = importlib.util.find_spec("robosuite")
        dist = importlib.metadata.distribution("robosuite")
    except (ImportError, ValueError, importlib.metadata.PackageNotFoundError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    root = Path(next(iter(spec.submodule_search_locations)))
    lic = next((f for f in dist.files or [] if f.name in ("LICENSE", "LICENSE.txt")), None)
    if lic is None or not (root / "models" / "assets" / "objects").is_dir():
        return None
    return PackageSource(root, dist.version, Path(str(dist.locate_file(lic))))


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _mesh_scale(xml: Path) -> tuple[float, float, float]:
    """The ``scale`` of the first ``<mesh>`` in an MJCF file (1 1 1 if absent)."""
    try:
        mesh = ET.parse(xml).getroot().find("./asset/mesh")
    except (OSError, ET.ParseError) as e:
        raise AssetError(f"cannot read {xml} ({e})") from None
    if mesh is None:
        raise AssetError(f"{xml} has no <mesh>: not a mesh object")
    vals = [float(v) for v in (mesh.get("scale") or "1 1 1").split()]
    if len(vals) != 3:
        raise AssetError(f"{xml}: mesh scale {mesh.get('scale')!r} is not three numbers")
    return vals[0], vals[1], vals[2]


def _licence(path: Path) -> tuple[str, str]:
    """(SPDX id, copyright line) of a licence file; only MIT is recognised."""
    text = path.read_text(encoding="utf-8", errors="replace")
    if not text.lstrip().startswith("MIT License"):
        raise AssetError(f"{path} is not the MIT licence: its meshes are not imported")
    line = next((ln.strip() for ln in text.splitlines() if ln.strip().startswith("Copyright")), "")
    return "MIT", line


def _source_key(src: PackageSource, objects: tuple[PackagedObject, ...]) -> str:
    """The hash of every source file and the importer's version (the library folder's key)."""
    objdir = src.root / "models" / "assets" / "objects"
    h = hashlib.sha256(f"{IMPORTER_VERSION}|{src.version}".encode())
    for o in objects:
        h.update(repr(o).encode())
        for rel in (o.xml, o.obj, o.texture):
            h.update(_sha256(objdir / rel).encode())
    return h.hexdigest()[:12]


def _texture(src: Path, tile_u: int, folder: Path, stem: str) -> str:
    """Writes the texture (repeated ``tile_u`` times across) into ``folder``, named by its
    content; returns the file name."""
    if tile_u == 1:
        data = src.read_bytes()
    else:
        import io

        from PIL import Image

        im = np.asarray(Image.open(src).convert("RGB"))
        buf = io.BytesIO()
        Image.fromarray(np.tile(im, (1, tile_u, 1))).save(buf, format="PNG")
        data = buf.getvalue()
    name = f"{stem}-{hashlib.sha256(data).hexdigest()[:16]}.png"
    (folder / name).write_bytes(data)
    return name


def _hulls(mesh: Any) -> list[Any]:
    """Convex collision hulls (<= 64 vertices each): the mesh's own hull when it is nearly
    convex (hull volume within 8 % of the mesh's), else CoACD's decomposition."""
    import trimesh

    from factory.assets.geometry import MAX_HULL_VERTICES
    from factory.assets.meshproc import decompose, reduce_hull

    hull = mesh.convex_hull
    if mesh.is_watertight and abs(mesh.volume) > 0.92 * hull.volume:
        if len(hull.vertices) > MAX_HULL_VERTICES:
            hull = reduce_hull(hull)
        return [hull]
    # CoACD's pieces may stick out of the mesh by a little (a bottle's went 0.8 mm under its
    # bottom, so it was placed pressing into its support): keep them inside its box.
    lo, hi = mesh.bounds
    return [
        trimesh.Trimesh(np.clip(np.asarray(h.vertices), lo, hi)).convex_hull
        for h in decompose(mesh, seed=0)
    ]


def import_robosuite(dest: Path, src: PackageSource | None = None) -> PackagedLibrary:
    """Imports robosuite's textured objects into ``dest/robosuite-<version>-<key>/`` (done
    once: an existing complete folder is reused; built aside and renamed into place).

    Raises:
        AssetError: robosuite is not installed, or a file of it is missing or malformed.
    """
    src = src or robosuite_source()
    if src is None:
        raise AssetError("robosuite is not installed: pip install robosuite to use its meshes")
    key = _source_key(src, ROBOSUITE)
    folder = Path(dest) / f"robosuite-{src.version}-{key}"
    if (folder / "metadata.json").is_file():
        return load_library(folder)
    Path(dest).mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=dest))
    try:
        _write_robosuite(tmp, src, key)
        try:
            os.rename(tmp, folder)
        except OSError:
            if not (folder / "metadata.json").is_file():
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return load_library(folder)


def _write_robosuite(folder: Path, src: PackageSource, key: str) -> None:
    from factory.assets.cache import write_obj
    from factory.assets.realmesh import clean, read_obj_uv, to_object_frame
    from factory.store import atomic_write_text

    objdir = src.root / "models" / "assets" / "objects"
    spdx, copyright_line = _licence(src.license_file)
    shutil.copyfile(src.license_file, folder / "LICENSE.robosuite.txt")
    entries = []
    hull_cache: dict[str, list[Any]] = {}
    for o in ROBOSUITE:
        sub = folder / o.name
        sub.mkdir()
        xml, obj, tex = objdir / o.xml, objdir / o.obj, (objdir / o.texture).resolve()
        mesh = to_object_frame(clean(read_obj_uv(obj)), _mesh_scale(xml))
        tm = mesh.trimesh()
        write_obj(tm, sub / "visual.obj", mesh.uv)
        tex_name = _texture(tex, o.tile_u, sub, Path(o.texture).stem)
        if o.obj + o.xml not in hull_cache:
            hull_cache[o.obj + o.xml] = _hulls(tm)
        collision = []
        for k, hull in enumerate(hull_cache[o.obj + o.xml]):
            write_obj(hull, sub / f"collision_{k}.obj")
            collision.append(f"{o.name}/collision_{k}.obj")
        rel = {
            f"models/assets/objects/{o.xml}": xml,
            f"models/assets/objects/{o.obj}": obj,
            f"models/assets/{Path(o.texture).relative_to('..')}": tex,
        }
        entries.append(
            {
                "name": o.name,
                "file": f"{o.name}/visual.obj",
                "texture": f"{o.name}/{tex_name}",
                "collision": collision,
                "category": o.category,
                "tags": list(o.phrases),
                "phrases": list(o.phrases),
                "accepts": list(o.accepts),
                "material": o.material,
                "density": o.density,
                "flat_top": o.flat_top,
                "finish": dict(
                    zip(("specular", "shininess", "reflectance"), o.finish, strict=True)
                ),
                "look": f"robosuite/{Path(o.texture).name}",
                "license": spdx,
                "license_file": "LICENSE.robosuite.txt",
                "extents": [float(v) for v in tm.extents],
                "vertices": len(tm.vertices),
                "faces": len(tm.faces),
                "provenance": {
                    "package": "robosuite",
                    "version": src.version,
                    "copyright": copyright_line,
                    "license": spdx,
                    "sources": {r: {"path": str(p), "sha256": _sha256(p)} for r, p in rel.items()},
                    "mesh_scale": list(_mesh_scale(xml)),
                    "texture_tiled_u": o.tile_u,
                    "importer": f"factory.assets.packaged/{IMPORTER_VERSION}",
                },
            }
        )
    meta = {
        "schema_version": PACKAGED_SCHEMA_VERSION,
        "package": "robosuite",
        "version": src.version,
        "key": key,
        "license": spdx,
        "copyright": copyright_line,
        "entries": entries,
    }
    atomic_write_text(folder / "metadata.json", json.dumps(meta, indent=2) + "\n")


def load_library(folder: Path) -> PackagedLibrary:
    """Reads an imported library's ``metadata.json`` (checking its ``schema_version``).

    Raises:
        AssetError: missing, unreadable, or of another schema version.
    """
    path = Path(folder) / "metadata.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise AssetError(f"{path} is unreadable ({e}); delete {folder} to re-import") from None
    version = data.get("schema_version") if isinstance(data, dict) else None
    if version != PACKAGED_SCHEMA_VERSION:
        raise AssetError(
            f"{path}: schema_version {version!r} is not {PACKAGED_SCHEMA_VERSION}; "
            f"delete {folder} to re-import"
        )
    return PackagedLibrary(Path(folder), list(data["entries"]), data["package"], data["version"])


_LIBRARIES: dict[Path, PackagedLibrary | None] = {}


def packaged_library(assets_dir: Path) -> PackagedLibrary | None:
    """The imported robosuite library for a run's assets folder (imported on first use, once
    per process), or ``None`` when robosuite is not installed (logged once)."""
    dest = (Path(assets_dir) / PACKAGED_DIR).resolve()
    known = _LIBRARIES.get(dest)
    if known is not None and not (known.folder / "metadata.json").is_file():
        del _LIBRARIES[dest]  # the folder was removed since: import again
    if dest not in _LIBRARIES:
        src = robosuite_source()
        if src is None:
            log.info("robosuite is not installed: procedural assets stand in for its meshes")
            _LIBRARIES[dest] = None
        else:
            _LIBRARIES[dest] = import_robosuite(dest, src)
    return _LIBRARIES[dest]


def _words(text: str) -> str:
    return " " + re.sub(r"[^a-z0-9\- ]+", " ", text.lower().replace("_", " ")) + " "


def choose(entries: list[dict[str, Any]], spec: AssetSpec) -> dict[str, Any] | None:
    """The textured entry for a request, or ``None`` (the procedural asset is used).

    An entry applies when its category is the request's, the request names no colour, style
    or condition (a "red can" or a "rusty can" keeps the procedural one, which can show
    them), any material it names is one the entry accepts, and the longest phrase of the
    category found in the text is one of the entry's (so "a tin can" is not the coke can).
    Of the entries that apply, the request's seed picks one (``seed % n`` over their sorted
    names): deterministic per seed.
    """
    from factory.assets.catalog import CATEGORIES

    if spec.colors or spec.style or set(spec.finish) - {"clean"}:
        return None
    cands = [e for e in entries if e.get("category") == spec.category]
    if spec.materials:
        cands = [e for e in cands if set(spec.materials) <= set(e.get("accepts", []))]
    if not cands:
        return None
    cat = CATEGORIES.get(spec.category)
    phrases = {spec.category.replace("_", " "), *(cat.synonyms if cat else ())}
    for e in cands:
        phrases |= set(e.get("phrases", []))
    text = _words(spec.text or spec.category)
    found = [p for p in phrases if re.search(rf"(?<![a-z]){re.escape(p)}(?![a-z])", text)]
    said = max(found, key=lambda p: (len(p), p)) if found else spec.category.replace("_", " ")
    hits = sorted(
        (e for e in cands if said in e.get("phrases", [])),
        key=lambda e: str(e.get("name", e["file"])),
    )
    if not hits:
        return None
    return hits[spec.seed % len(hits)]


__all__ = [
    "PACKAGED_DIR",
    "PACKAGED_SCHEMA_VERSION",
    "ROBOSUITE",
    "PackageSource",
    "PackagedLibrary",
    "PackagedObject",
    "choose",
    "import_robosuite",
    "load_library",
    "packaged_library",
    "robosuite_source",
]
