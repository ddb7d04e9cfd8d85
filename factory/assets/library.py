"""The asset library: one interface over three backends, with a content-addressed cache.

``AssetLibrary(assets_dir, backend=...)``:

* ``procedural`` (default, offline): :mod:`.procedural` generators for every category in
  :data:`~.catalog.CATEGORIES`;
* ``mesh_library``: a folder of GLB/OBJ/PLY/STL files described by ``metadata.json``
  (``[{"file", "category", "tags", "license", "y_up"?}]``); the best entry for the text
  (category match, then tag overlap) is repaired, decimated, scaled and decomposed with CoACD;
* ``trellis``: an HTTP text-to-3D server (``POST <url>`` with ``{"prompt", "seed"}`` JSON,
  answering mesh bytes (GLB/PLY/OBJ; ``Content-Type`` or ``format`` says which); timeouts,
  retries, the same post-processing. On failure it falls back to ``procedural`` when
  ``fallback`` is set (logged and recorded in the asset's provenance), else raises.

Every asset records its license and provenance in ``meta.json``.
"""

from __future__ import annotations

import json
import logging
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from factory.assets.cache import asset_id_for, build, cached, write_obj
from factory.assets.catalog import CATEGORIES
from factory.assets.geometry import Support
from factory.assets.meshproc import decompose, load_mesh, repair, to_object_frame
from factory.assets.physics import material
from factory.assets.procedural import AssetError, AssetSpec, generate
from factory.assets.resolver import Resolution, resolve
from factory.schema import AssetMeta

log = logging.getLogger(__name__)

BACKENDS: tuple[str, ...] = ("procedural", "mesh_library", "trellis")


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
    """

    def __init__(
        self,
        assets_dir: str | Path,
        backend: str = "procedural",
        library_dir: str | Path | None = None,
        trellis: TrellisConfig | None = None,
        fallback: bool = True,
    ) -> None:
        if backend not in BACKENDS:
            raise AssetError(f"asset backend {backend!r} is not one of {', '.join(BACKENDS)}")
        if backend == "mesh_library" and library_dir is None:
            raise AssetError("the mesh_library backend needs assets.library_dir=FOLDER")
        self.assets_dir = Path(assets_dir)
        self.backend = backend
        self.library_dir = Path(library_dir) if library_dir else None
        self.trellis = trellis or TrellisConfig()
        self.fallback = fallback

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
        )

    # ---- front
    def from_text(self, text: str, seed: int = 0, dims: Any = None) -> tuple[AssetMeta, Resolution]:
        """The asset for a free-text request (``dims`` in m overrides the text's size)."""
        res = resolve(text, seed=seed)
        if dims is not None:
            from factory.assets.procedural import check_dims

            res.spec.dims = check_dims(dims)
        if res.approximated:
            log.info("asset request %r: %s", text, "; ".join(res.notes))
        return self.get(res.spec), res

    def get(self, spec: AssetSpec) -> AssetMeta:
        """The asset for a resolved spec (cached)."""
        if self.backend == "procedural":
            return self._procedural(spec)
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
            parts: list[dict[str, Any]] = []
            collision: list[str] = []
            for k, p in enumerate(gen.shape.parts):
                write_obj(p.visual, folder / f"visual_{k}.obj")
                mat = material(p.material)
                parts.append(
                    {
                        "file": f"visual_{k}.obj",
                        "name": p.name,
                        "material": p.material,
                        "rgba": list(p.rgba),
                        "metallic": mat.metallic,
                        "roughness": mat.roughness,
                    }
                )
                for c in p.collision:
                    name = f"collision_{len(collision)}.obj"
                    write_obj(c, folder / name)
                    collision.append(name)
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
                containers=[
                    {"name": c.name, "lo": [float(v) for v in c.lo], "hi": [float(v) for v in c.hi]}
                    for c in gen.shape.containers
                ],
                mass=gen.mass,
                friction=gen.friction,
                materials=list(gen.materials),
                request=spec.key(),
            )

        return build(self.assets_dir, asset_id, fill)

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


def _support(s: Support) -> dict[str, Any]:
    return {
        "name": s.name,
        "z": float(s.z),
        "rect": [float(v) for v in s.rect],
        "clearance": float(s.clearance),
    }


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
