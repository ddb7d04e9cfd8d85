"""The asset library: one interface over three backends, with a content-addressed cache.

``AssetLibrary(assets_dir, backend=...)``:

* ``procedural`` (default, offline): :mod:`.procedural` generators for every category in
  :data:`~.catalog.CATEGORIES`;
* ``mesh_library``: a folder of GLB/OBJ/PLY/STL files described by ``metadata.json``
  (``[{"file", "category", "tags", "license", "y_up"?}]``); the best entry for the text
  (category match, then tag overlap) is repaired, decimated, scaled and decomposed with CoACD.
  A library with ``{"schema_version", "entries"}`` may hold textured entries (``texture``,
  ``collision``, ``density``: :mod:`.realmesh`), such as the one :mod:`.packaged` imports;
  those are used as they are, scaled by the request's size words;
* ``trellis``: an HTTP text-to-3D server (``POST <url>`` with ``{"prompt", "seed"}`` JSON,
  answering mesh bytes (GLB/PLY/OBJ; ``Content-Type`` or ``format`` says which); timeouts,
  retries, the same post-processing. On failure it falls back to ``procedural`` when
  ``fallback`` is set (logged and recorded in the asset's provenance), else raises.

With ``real_meshes`` (``assets.real_meshes``, on by default) the procedural backend first
looks for a textured real mesh of the request in the packages installed (robosuite's can,
bottle, milk, cereal, bread and lemon: :mod:`.packaged`, imported once into
``assets/packaged/``); "a coke can" is then robosuite's can, "a red can" still a procedural
one. Every asset records its license and provenance in ``meta.json``. Procedural parts are
textured (:mod:`factory.textures`): each part's OBJ carries UVs in the part's mapping
(:mod:`.uv`), its PNG lies in the asset folder (a hard link into ``assets/textures/``), and its
meta entry names the texture, the look, the weathering and the MuJoCo finish.
"""

from __future__ import annotations

import json
import logging
import math
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from factory.assets.articulation import JointSpec
from factory.assets.cache import asset_id_for, build, cached, write_obj
from factory.assets.catalog import CATEGORIES
from factory.assets.geometry import Container, Part, Support
from factory.assets.meshproc import decompose, load_mesh, repair, to_object_frame
from factory.assets.physics import material
from factory.assets.procedural import AssetError, AssetSpec, Generated, generate
from factory.assets.resolver import Resolution, resolve
from factory.assets.uv import uv_of
from factory.schema import AssetMeta
from factory.schema.asset import Articulation, HandleMeta, JointMeta, LinkMeta

log = logging.getLogger(__name__)

BACKENDS: tuple[str, ...] = ("procedural", "mesh_library", "trellis")

TEXTURES_DIR = "textures"
"""The content-addressed texture cache inside the assets folder (``assets/textures/``);
each asset folder holds hard links (or copies) of the images its parts use."""


@dataclass
class TrellisConfig:
    """The text-to-3D server: URL, timeout (s) per request, retries, back-off (s)."""

    url: str = "http://127.0.0.1:8000/generate"
    timeout: float = 120.0
    retries: int = 2
    backoff: float = 1.0


class AssetLibrary:
    """Assets by text or spec, cached under ``assets_dir``.

    Args:
        assets_dir: the run's ``assets/`` folder.
        backend: ``procedural``, ``mesh_library`` or ``trellis``.
        library_dir: the mesh library folder (``mesh_library`` backend).
        trellis: the server settings (``trellis`` backend).
        fallback: on a backend failure, fall back to ``procedural`` (logged) instead of raising.
        texture_size: size (px) of the procedural parts' textures (64..512).
        real_meshes: the procedural backend uses installed packages' textured meshes where one
            matches the request (:func:`.packaged.choose`).
        articulated: articulated categories are built with moving links (``meta.articulation``;
            request key ``rig: joints``); off, as one rigid body, closed (``rig: fused``).
            Other categories are the same either way.
    """

    def __init__(
        self,
        assets_dir: str | Path,
        backend: str = "procedural",
        library_dir: str | Path | None = None,
        trellis: TrellisConfig | None = None,
        fallback: bool = True,
        texture_size: int = 256,
        real_meshes: bool = True,
        articulated: bool = False,
    ) -> None:
        if backend not in BACKENDS:
            raise AssetError(f"asset backend {backend!r} is not one of {', '.join(BACKENDS)}")
        if backend == "mesh_library" and library_dir is None:
            raise AssetError("the mesh_library backend needs assets.library_dir=FOLDER")
        from factory.textures.cache import SIZES

        if texture_size not in SIZES:
            raise AssetError(
                f"assets.texture_size={texture_size} is not one of {', '.join(map(str, SIZES))}"
            )
        self.texture_size = int(texture_size)
        self.assets_dir = Path(assets_dir)
        self.backend = backend
        self.library_dir = Path(library_dir) if library_dir else None
        self.trellis = trellis or TrellisConfig()
        self.fallback = fallback
        self.real_meshes = bool(real_meshes)
        self.articulated = bool(articulated)

    @classmethod
    def from_config(cls, cfg: Any, assets_dir: str | Path) -> AssetLibrary:
        """The library described by the ``assets`` config section."""
        return cls(
            assets_dir,
            backend=cfg.backend,
            library_dir=cfg.library_dir,
            trellis=TrellisConfig(
                url=cfg.trellis_url, timeout=cfg.trellis_timeout, retries=cfg.trellis_retries
            ),
            fallback=cfg.fallback,
            texture_size=getattr(cfg, "texture_size", 256),
            real_meshes=getattr(cfg, "real_meshes", True),
            articulated=getattr(cfg, "articulated", False),
        )

    def articulated_copy(self) -> AssetLibrary:
        """This library with :attr:`articulated` on (the same folder, backend and settings):
        for a request whose task needs doors and drawers that move."""
        import copy

        out = copy.copy(self)
        out.articulated = True
        return out

    # ---- front
    def from_text(
        self, text: str, seed: int = 0, dims: Any = None, finish: tuple[str, ...] = ()
    ) -> tuple[AssetMeta, Resolution]:
        """The asset for a free-text request (``dims`` in m overrides the text's size;
        ``finish`` adds condition kinds, e.g. the scene request's ``("dust",)``)."""
        res = resolve(text, seed=seed)
        rigid = CATEGORIES.get(res.spec.category)
        if self.articulated and rigid is not None and rigid.articulated_as:
            res = self._articulated(res, rigid.articulated_as, seed)
        if finish:
            res.spec.finish = tuple(dict.fromkeys((*res.spec.finish, *finish)))
        if dims is not None:
            from factory.assets.procedural import check_dims

            res.spec.dims = check_dims(dims)
        if res.approximated:
            log.info("asset request %r: %s", text, "; ".join(res.notes))
        return self.get(res.spec), res

    @staticmethod
    def _articulated(res: Resolution, name: str, seed: int) -> Resolution:
        """The resolution of the articulated category ``name`` that stands for the rigid one
        ``res`` found (``Category.articulated_as``): a refrigerator asked for where assets
        are built articulated is an ``upright_fridge`` with a door that opens."""
        moving = resolve(name.replace("_", " "), seed=seed, allow_fallback=False)
        if moving.spec.category != name:
            raise AssetError(
                f"catalogue: {res.spec.category}'s articulated_as {name!r} reads as "
                f"{moving.spec.category!r}: give {name} a synonym that names it"
            )
        log.info(
            "asset request %r: %s, built articulated as %s", res.spec.text, res.spec.category, name
        )
        return moving

    def get(self, spec: AssetSpec) -> AssetMeta:
        """The asset for a resolved spec (cached)."""
        if spec.texture_size != self.texture_size:
            spec = replace(spec, texture_size=self.texture_size)
        cat = CATEGORIES.get(spec.category)
        if cat is not None and cat.articulated:
            spec = replace(spec, rig="joints" if self.articulated else "fused")
        if self.backend == "procedural":
            return (self._real_mesh(spec) if self.real_meshes else None) or self._procedural(spec)
        key = spec.key() | {"text": spec.text}
        asset_id = asset_id_for(self.backend, key)
        hit = cached(self.assets_dir, asset_id)
        if hit is not None:
            return hit
        try:
            if self.backend == "mesh_library":
                return build(
                    self.assets_dir, asset_id, lambda d: self._from_library(spec, d, asset_id)
                )
            return build(self.assets_dir, asset_id, lambda d: self._from_trellis(spec, d, asset_id))
        except AssetError as e:
            if not self.fallback:
                raise
            log.warning(
                "%s backend failed for %r (%s); falling back to procedural",
                self.backend,
                spec.text or spec.category,
                e,
            )
            meta = self._procedural(spec)
            meta.provenance.setdefault("fallback_from", self.backend)
            return meta

    # ---- procedural
    def _procedural(self, spec: AssetSpec) -> AssetMeta:
        asset_id = asset_id_for("procedural", spec.key())

        def fill(folder: Path) -> AssetMeta:
            gen = generate(spec)
            write_obj(gen.visual, folder / "visual.obj")
            groups = _same_look(gen.shape.parts)
            parts = [self._textured_part(group, k, spec, folder) for k, group in enumerate(groups)]
            collision: list[str] = []
            pieces: dict[int, list[int]] = {}  # part (by id) -> its collision indices
            for p in gen.shape.parts:
                for c in p.collision:
                    name = f"collision_{len(collision)}.obj"
                    write_obj(c, folder / name)
                    pieces.setdefault(id(p), []).append(len(collision))
                    collision.append(name)
            if gen.shape.joints:
                for k, group in enumerate(groups):
                    parts[k]["link"] = group[0].link
            return AssetMeta(
                asset_id=asset_id,
                backend="procedural",
                visual="visual.obj",
                extents=[float(v) for v in gen.visual.extents],
                collision=collision,
                license="CC0-1.0",
                provenance={
                    "generator": f"factory.assets.templates/{spec.category}",
                    "seed": spec.seed,
                    "text": spec.text,
                },
                category=spec.category,
                visual_parts=parts,
                supports=[_support(s) for s in gen.shape.supports],
                containers=[_container(c) for c in gen.shape.containers],
                mass=gen.mass,
                friction=gen.friction,
                materials=list(gen.materials),
                request=spec.key(),
                articulation=_articulation(gen, groups, pieces),
            )

        return build(self.assets_dir, asset_id, fill)

    def _textured_part(
        self, group: list[Part], k: int, spec: AssetSpec, folder: Path
    ) -> dict[str, Any]:
        """Writes visual part ``k`` (parts of one material and colour, one mesh) with its UVs
        and its texture into ``folder``; returns its meta entry."""
        import trimesh

        from factory.textures.appearance import appearance
        from factory.textures.cache import link_or_copy

        p = group[0]
        mat = material(p.material)
        app = appearance(
            p.material,
            p.rgba,
            self.assets_dir / TEXTURES_DIR,
            seed=spec.seed,
            kinds=spec.finish,
            size=spec.texture_size,
            metallic=mat.metallic,
            roughness=mat.roughness,
        )
        mesh = trimesh.util.concatenate([q.visual for q in group])
        assert isinstance(mesh, trimesh.Trimesh)
        uv = np.concatenate([uv_of(q.visual, q.mapping, q.labels) for q in group]) / app.tile
        if len(uv) != len(mesh.faces):  # pragma: no cover - concatenation keeps every face
            raise AssetError(f"visual part {p.name!r}: {len(uv)} UV faces, {len(mesh.faces)} faces")
        write_obj(mesh, folder / f"visual_{k}.obj", uv)
        tex_file = f"{app.texture.key}.png"
        link_or_copy(app.texture.path, folder / tex_file)
        return {
            "file": f"visual_{k}.obj",
            "name": p.name,
            "parts": [q.name for q in group],
            "material": p.material,
            "rgba": [float(c) for c in app.colour],
            "metallic": app.metallic,
            "roughness": app.roughness,
            "texture": tex_file,
            "texture_gain": list(app.texture.gain),
            "tinted": app.tinted,
            "look": app.look,
            "weathering": list(app.weathering),
            "specular": app.finish.specular,
            "shininess": app.finish.shininess,
            "reflectance": app.finish.reflectance,
        }

    # ---- textured real meshes of installed packages
    def _real_mesh(self, spec: AssetSpec) -> AssetMeta | None:
        """The textured real mesh for ``spec`` from an installed package, or ``None`` (no
        package, no entry for the request, or the import failed: logged)."""
        if spec.category not in _PACKAGED_CATEGORIES:
            return None
        from factory.assets.packaged import choose, packaged_library

        try:
            lib = packaged_library(self.assets_dir)
        except AssetError as e:
            log.warning("packaged meshes unavailable (%s); using procedural assets", e)
            return None
        entry = choose(lib.entries, spec) if lib is not None else None
        if lib is None or entry is None:
            return None
        try:
            return self._textured_entry(lib.folder, entry, spec)
        except AssetError as e:
            log.warning("packaged mesh %s failed (%s); using procedural", entry.get("name"), e)
            return None

    def _textured_entry(self, folder: Path, entry: dict[str, Any], spec: AssetSpec) -> AssetMeta:
        """The asset of a textured library entry, scaled by the request's size words (its
        dimensions over the category's typical ones); one asset per entry and scale."""
        from factory.assets.realmesh import build_textured_asset

        factors = _factors(spec)
        key = {
            "library": str(entry.get("provenance", {}).get("package", folder.name)),
            "library_key": folder.name,
            "entry": str(entry.get("name", entry["file"])),
            "scale": list(factors),
        }
        asset_id = asset_id_for("mesh_library", key)
        return build(
            self.assets_dir,
            asset_id,
            lambda d: build_textured_asset(
                folder, entry, factors, d, asset_id, "mesh_library", key | spec.key()
            ),
        )

    # ---- mesh library
    def _library_entries(self) -> list[dict[str, Any]]:
        assert self.library_dir is not None
        meta_path = self.library_dir / "metadata.json"
        try:
            entries = json.loads(meta_path.read_text())
        except FileNotFoundError:
            raise AssetError(f"mesh library {self.library_dir} has no metadata.json") from None
        except json.JSONDecodeError as e:
            raise AssetError(f"{meta_path} is not valid JSON ({e.msg})") from None
        if isinstance(entries, dict):  # {"schema_version", "entries"}: an imported library
            if entries.get("schema_version") != 1:
                raise AssetError(
                    f"{meta_path}: schema_version {entries.get('schema_version')!r} is not 1; "
                    "re-import the library"
                )
            entries = entries.get("entries")
        if not isinstance(entries, list) or not all(
            isinstance(e, dict) and "file" in e for e in entries
        ):
            raise AssetError(f"{meta_path} must be a list of {{file, category, tags, license}}")
        return entries

    def _from_library(self, spec: AssetSpec, folder: Path, asset_id: str) -> AssetMeta:
        entries = self._library_entries()
        words = set((spec.text or spec.category).lower().replace("_", " ").split())

        def score(e: dict[str, Any]) -> tuple[int, int]:
            tags = {t.lower() for t in e.get("tags", [])}
            return (int(e.get("category") == spec.category), len(words & tags))

        best = max(entries, key=score)
        if score(best) == (0, 0):
            raise AssetError(
                f"no mesh in {self.library_dir} matches {spec.text or spec.category!r}"
            )
        assert self.library_dir is not None
        if best.get("texture"):
            from factory.assets.realmesh import build_textured_asset

            return build_textured_asset(
                self.library_dir, best, _factors(spec), folder, asset_id, "mesh_library", spec.key()
            )
        path = self.library_dir / str(best["file"])
        mesh = load_mesh(path)
        return self._finish(
            mesh,
            spec,
            folder,
            asset_id,
            "mesh_library",
            best.get("license", "unknown"),
            {"source_file": best["file"], "tags": best.get("tags", [])},
            y_up=bool(best.get("y_up", False)),
        )

    # ---- trellis
    def _from_trellis(self, spec: AssetSpec, folder: Path, asset_id: str) -> AssetMeta:
        cfg = self.trellis
        body = json.dumps(
            {"prompt": spec.text or spec.category.replace("_", " "), "seed": spec.seed}
        ).encode()
        last: Exception | None = None
        for attempt in range(cfg.retries + 1):
            try:
                req = urllib.request.Request(
                    cfg.url, data=body, method="POST", headers={"Content-Type": "application/json"}
                )
                with urllib.request.urlopen(req, timeout=cfg.timeout) as r:
                    data = r.read()
                    ctype = r.headers.get("Content-Type", "")
                fmt = _format(ctype, data)
                mesh = load_mesh(data, file_type=fmt)
                return self._finish(
                    mesh,
                    spec,
                    folder,
                    asset_id,
                    "trellis",
                    "see server",
                    {"server": cfg.url, "attempts": attempt + 1, "format": fmt},
                    y_up=fmt == "glb",
                )
            except (urllib.error.URLError, TimeoutError, OSError, AssetError) as e:
                last = e
                log.warning("trellis request %d/%d failed: %s", attempt + 1, cfg.retries + 1, e)
                if attempt < cfg.retries:
                    time.sleep(cfg.backoff * (2**attempt))
        raise AssetError(
            f"the text-to-3D server at {cfg.url} failed after {cfg.retries + 1} attempt(s): {last}"
        )

    # ---- shared post-processing
    def _finish(
        self,
        mesh: Any,
        spec: AssetSpec,
        folder: Path,
        asset_id: str,
        backend: str,
        license: str,
        provenance: dict[str, Any],
        y_up: bool,
    ) -> AssetMeta:
        m = repair(mesh)
        cat = CATEGORIES.get(spec.category)
        m = (
            to_object_frame(m, dims=spec.dims, y_up=y_up)
            if spec.dims
            else to_object_frame(m, height=cat.dims[2] if cat else 0.3, y_up=y_up)
        )
        hulls = decompose(m, seed=spec.seed)
        write_obj(m, folder / "visual.obj")
        names = []
        for k, h in enumerate(hulls):
            write_obj(h, folder / f"collision_{k}.obj")
            names.append(f"collision_{k}.obj")
        mats = spec.materials or (cat.materials if cat else ("plastic", "plastic"))
        mat = material(mats[0])
        volume = float(m.volume) if m.is_watertight else float(sum(h.volume for h in hulls))
        ext = m.extents
        return AssetMeta(
            asset_id=asset_id,
            backend=backend,
            visual="visual.obj",
            extents=[float(v) for v in ext],
            collision=names,
            license=license,
            provenance=provenance | {"text": spec.text, "seed": spec.seed},
            category=spec.category,
            supports=[
                {
                    "name": "top",
                    "z": float(ext[2]),
                    "rect": [
                        float(-ext[0] / 2),
                        float(-ext[1] / 2),
                        float(ext[0] / 2),
                        float(ext[1] / 2),
                    ],
                }
            ],
            mass=volume * mat.density * (cat.fill if cat else 1.0),
            friction=mat.friction,
            materials=list(mats),
            request=spec.key(),
        )


_PACKAGED_CATEGORIES = frozenset({"can", "bottle", "milk_carton", "cereal_box", "bread", "lemon"})
"""Categories some installed package may have a textured mesh of (a cheap test before the
package is looked for)."""


def _factors(spec: AssetSpec) -> tuple[float, float, float]:
    """Per-axis scale of a real mesh for a request: its dimensions over the category's typical
    ones ("a small can": 0.78 each), 1 without dimensions or category."""
    cat = CATEGORIES.get(spec.category)
    if spec.dims is None or cat is None:
        return (1.0, 1.0, 1.0)
    f = [round(float(d) / float(c), 4) for d, c in zip(spec.dims, cat.dims, strict=True)]
    return (f[0], f[1], f[2])


def _same_look(parts: list[Part]) -> list[list[Part]]:
    """The parts grouped by link, material and colour, in first-seen order: each group
    becomes one visual mesh (a table's top and legs are drawn at once: fewer draws per camera
    frame; a moving link's pieces stay its own)."""
    groups: dict[tuple[str, str, tuple[float, ...]], list[Part]] = {}
    for p in parts:
        key = (p.link, p.material, tuple(round(float(c), 4) for c in p.rgba))
        groups.setdefault(key, []).append(p)
    return list(groups.values())


def _support(s: Support) -> dict[str, Any]:
    out: dict[str, Any] = {
        "name": s.name,
        "z": float(s.z),
        "rect": [float(v) for v in s.rect],
        "clearance": float(s.clearance),
    }
    return out | _on_link(s)


def _container(c: Container) -> dict[str, Any]:
    out = {"name": c.name, "lo": [float(v) for v in c.lo], "hi": [float(v) for v in c.hi]}
    return out | _on_link(c)


def _on_link(item: Support | Container) -> dict[str, Any]:
    """``link`` and ``access`` of a support or container, only where set (a rigid asset's
    meta stays as it was)."""
    return {k: getattr(item, k) for k in ("link", "access") if getattr(item, k)}


def _articulation(
    gen: Generated, groups: list[list[Part]], pieces: dict[int, list[int]]
) -> Articulation | None:
    """The asset's ``articulation`` from the shape's joints (``None`` without joints):
    each link claims its parts' collision pieces and its visual groups; handles list their
    parts' pieces."""
    shape = gen.shape
    if not shape.joints:
        return None
    links, joints = [], []
    for j in shape.joints:
        own = [p for p in shape.parts if p.link == j.link]
        handles = []
        for h in shape.handles:
            mine = [k for p in own if p.handle == h.name for k in pieces.get(id(p), [])]
            if any(p.handle == h.name for p in own) or (
                not any(p.handle == h.name for p in shape.parts) and _handle_link(gen, h) == j.link
            ):
                handles.append(replace(h, collision=mine))
        links.append(
            LinkMeta(
                name=j.link,
                parent=j.parent,
                collision=[k for p in own for k in pieces.get(id(p), [])],
                visual=[k for k, g in enumerate(groups) if g[0].link == j.link],
                handles=handles,
            )
        )
        phys = gen.physics[j.name]
        ref = math.radians(phys.springref) if j.kind == "hinge" else phys.springref
        joints.append(
            JointMeta(
                name=j.name,
                kind=j.kind,  # type: ignore[arg-type]
                role=j.role,  # type: ignore[arg-type]
                link=j.link,
                anchor=list(j.anchor),
                axis=list(j.axis),
                range=list(j.range),
                damping=phys.damping,
                frictionloss=phys.frictionloss,
                armature=phys.armature,
                stiffness=phys.stiffness,
                springref=ref,
                rest=_rest(j, phys.stiffness, ref, phys.frictionloss),
            )
        )
    assert gen.swept is not None
    return Articulation(links=links, joints=joints, swept=gen.swept)


def _handle_link(gen: Generated, h: HandleMeta) -> str:
    """The link an ``edge`` handle (no parts of its own) belongs to: the link whose parts'
    bounds hold its centre (the root if none)."""
    c = np.asarray(h.center)
    for p in gen.shape.parts:
        lo, hi = p.visual.bounds
        if p.link and (c >= lo - 1e-6).all() and (c <= hi + 1e-6).all():
            return p.link
    return ""


def _rest(
    j: JointSpec, stiffness: float = 0.0, springref: float = 0.0, friction: float = 0.0
) -> list[list[float]]:
    """Where a joint holds by itself, where gravity does no work on it (a hinge about a
    vertical axis, a horizontal slide): its whole range without a spring; with one (stiffness
    N m/rad or N/m towards ``springref``), where the spring's pull is within the joint's dry
    ``friction`` (``|q - springref| <= friction / stiffness``), within the range. Else not known
    yet (empty)."""
    vertical = abs(abs(j.axis[2]) - 1.0) < 1e-9
    level = abs(j.axis[2]) < 1e-9
    if not ((j.kind == "hinge" and vertical) or (j.kind == "slide" and level)):
        return []
    lo, hi = float(j.range[0]), float(j.range[1])
    if stiffness > 0:
        reach = friction / stiffness
        lo, hi = max(lo, springref - reach), min(hi, springref + reach)
        if lo > hi:  # the spring pulls the link to a limit: it rests there
            return (
                [[float(j.range[0])] * 2] if springref < j.range[0] else [[float(j.range[1])] * 2]
            )
    return [[lo, hi]]


def _format(content_type: str, data: bytes) -> str:
    ct = content_type.lower()
    if "gltf" in ct or data[:4] == b"glTF":
        return "glb"
    if "ply" in ct or data[:3] == b"ply":
        return "ply"
    if "stl" in ct:
        return "stl"
    return "obj"


__all__ = ["BACKENDS", "AssetLibrary", "TrellisConfig"]
