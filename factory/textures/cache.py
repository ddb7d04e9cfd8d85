"""Making textures and caching them as content-addressed PNG files.

A texture is named by the SHA-256 of what makes it (generator, its version, parameters,
seed, size, weathering and the colour the weathering was composed on): the same
:class:`TextureSpec` always gives the same bytes, and a file that exists is never made again.
Files are written atomically, so processes sharing a cache folder (SLURM array tasks on one
run directory) each see either no file or a whole one. Each PNG carries a ``factory`` text
chunk (JSON with ``schema_version``, the key, the gain and the spec).

Images are stored divided by their *gain*, per channel (the 99.5th percentile of the detail
map's channel, at least 1), so they fit in 8 bits; the material that uses one multiplies its
colour by the gain, channel by channel (dust on dark walnut brightens blue four times as much
as red: one gain for all three would clip the material's red).
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import zlib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from factory.store import atomic_write_bytes
from factory.textures.registry import VERSION, TextureError, generator

log = logging.getLogger(__name__)

TEXTURE_SCHEMA_VERSION = 1
SIZES = (64, 128, 256, 512)
"""Texture sizes (px) accepted; 256 is the default."""
DEFAULT_SIZE = 256
VARIANTS = 4
"""Distinct images per look: an asset's seed picks one (``seed % VARIANTS``), so a run holds
a few images per material instead of one per object."""
COLOUR_STEP = 0.05
"""Colours that weathering is composed on are rounded to this step (fewer distinct files)."""

_GAINS: dict[str, tuple[float, float, float]] = {}


@dataclass(frozen=True)
class TextureSpec:
    """What makes a texture image.

    Attributes:
        generator: key of :data:`~.registry.GENERATORS`.
        params: the generator's keyword arguments (sorted pairs).
        seed: the random seed (a variant number, ``0 .. VARIANTS - 1``, for looks).
        size: width and height (px), one of :data:`SIZES`.
        weathering: weathering kinds applied on top (sorted).
        family: the surface's family (what weathering does to it).
        base: the colour (linear RGB, 0..1) the weathering is composed on: the part's colour
            for tinted looks (white for untinted ones; unused without weathering).
        normalise: scale the detail map to mean luminance 1 (tinted looks).
    """

    generator: str
    params: tuple[tuple[str, Any], ...] = ()
    seed: int = 0
    size: int = DEFAULT_SIZE
    weathering: tuple[str, ...] = ()
    family: str = ""
    base: tuple[float, float, float] = (1.0, 1.0, 1.0)
    normalise: bool = True

    def record(self) -> dict[str, Any]:
        """The JSON-able description that the key hashes."""
        d = asdict(self)
        d["params"] = [list(p) for p in self.params]
        d["weathering"] = sorted(self.weathering)
        d["base"] = [round(float(c), 4) for c in self.base]
        d["version"] = VERSION
        return d

    def key(self) -> str:
        """``<generator>-<20 hex>`` from :meth:`record`."""
        blob = json.dumps(self.record(), sort_keys=True).encode()
        return f"{self.generator}-{hashlib.sha256(blob).hexdigest()[:20]}"


@dataclass(frozen=True)
class Texture:
    """A cached texture file.

    Attributes:
        path: the PNG.
        key: its content key (the file is ``<key>.png``).
        gain: multiply the material colour by this, per channel (RGB; the image was divided
            by it).
    """

    path: Path
    key: str
    gain: tuple[float, float, float]


def quantise(rgb: Any) -> tuple[float, float, float]:
    """A colour rounded to :data:`COLOUR_STEP` (and clipped to 0.02..1)."""
    c = np.clip(np.round(np.asarray(rgb, float)[:3] / COLOUR_STEP) * COLOUR_STEP, 0.02, 1.0)
    return (float(c[0]), float(c[1]), float(c[2]))


def make_image(spec: TextureSpec) -> tuple[np.ndarray, tuple[float, float, float]]:
    """Generates a texture: ``(image, gain)``, the image (size, size, 3) uint8 and the gain
    per channel.

    Raises:
        TextureError: unknown generator or size.
    """
    from factory.textures.noise import luma
    from factory.textures.weathering import weather

    if spec.size not in SIZES:
        raise TextureError(f"texture size {spec.size} px is not one of {SIZES}")
    fn = generator(spec.generator)
    salt = zlib.crc32(spec.generator.encode())
    rng = np.random.default_rng([spec.seed, salt])
    detail = np.asarray(fn(rng, spec.size, **dict(spec.params)), np.float32)
    if spec.normalise:
        detail = detail / max(float(luma(detail).mean()), 1e-3)
    if spec.weathering:
        base = np.maximum(np.asarray(spec.base, np.float32), 0.02)
        wrng = np.random.default_rng([spec.seed, salt, 1])
        weathered = weather(detail * base, tuple(sorted(spec.weathering)), spec.family, wrng)
        detail = (weathered / base).astype(np.float32)
    top = np.percentile(detail.reshape(-1, 3), 99.5, axis=0)
    g = np.round(np.maximum(1.0, top), 4)
    image = np.clip(detail / g.astype(np.float32) * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return image, (float(g[0]), float(g[1]), float(g[2]))


def png_with_record(image: np.ndarray, record: dict[str, Any]) -> bytes:
    """PNG bytes of an (H, W, 3) uint8 image with ``record`` as a ``factory`` text chunk."""
    from PIL import Image, PngImagePlugin

    info = PngImagePlugin.PngInfo()
    info.add_text("factory", json.dumps(record, sort_keys=True))
    buf = io.BytesIO()
    Image.fromarray(image, "RGB").save(buf, format="PNG", pnginfo=info, compress_level=4)
    return buf.getvalue()


def read_record(path: str | Path) -> dict[str, Any]:
    """The ``factory`` record of a texture PNG (header only; the pixels are not decoded).

    Raises:
        TextureError: not a texture written here, or another schema version.
    """
    from PIL import Image

    try:
        with Image.open(path) as im:
            text = getattr(im, "text", {}).get("factory")
    except (OSError, SyntaxError) as e:
        raise TextureError(f"{path} is not a readable PNG ({e}); delete it to remake it") from None
    try:
        record: dict[str, Any] = json.loads(text) if text else {}
    except json.JSONDecodeError:
        record = {}
    if record.get("schema_version") != TEXTURE_SCHEMA_VERSION:
        raise TextureError(
            f"{path} has texture schema_version {record.get('schema_version')!r}, this factory "
            f"reads {TEXTURE_SCHEMA_VERSION}: delete it to remake it"
        )
    return record


def texture_file(spec: TextureSpec, folder: str | Path) -> Texture:
    """The cached texture of ``spec`` in ``folder`` (``<key>.png``), made if missing.

    Raises:
        TextureError: unknown generator or size, or a damaged cached file that cannot be
            replaced.
    """
    key = spec.key()
    path = Path(folder) / f"{key}.png"
    if path.is_file():
        gain = _GAINS.get(key)
        if gain is None:
            try:
                r, g, b = (float(v) for v in read_record(path)["gain"])
                gain = (r, g, b)
            except (TextureError, KeyError, TypeError, ValueError) as e:
                log.warning("texture %s is damaged (%s); making it again", path, e)
                gain = None
        if gain is not None:
            _GAINS[key] = gain
            return Texture(path, key, gain)
    image, gain = make_image(spec)
    record = {
        "schema_version": TEXTURE_SCHEMA_VERSION,
        "key": key,
        "gain": list(gain),
        "spec": spec.record(),
    }
    atomic_write_bytes(path, png_with_record(image, record))
    _GAINS[key] = gain
    return Texture(path, key, gain)


def link_or_copy(src: Path, dst: Path) -> None:
    """``dst`` as a hard link to ``src`` (no extra disk), or a copy across file systems."""
    import shutil

    dst.parent.mkdir(parents=True, exist_ok=True)
    if dst.exists():
        return
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)


def default_folder() -> Path:
    """Where textures go when no run directory is at hand: ``$FACTORY_TEXTURE_CACHE``, else
    ``$XDG_CACHE_HOME/factory/textures`` (``~/.cache/factory/textures``)."""
    env = os.environ.get("FACTORY_TEXTURE_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "factory" / "textures"
