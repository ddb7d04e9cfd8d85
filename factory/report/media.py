"""The page's images: data URIs inside the page, or files under ``report_files/`` beside it.

``report.html`` lives in the run directory, so a relative ``src`` (``report_files/...``,
``scenes/<id>/renders/top.png``) resolves from ``file://`` and over any static file server.
"""

from __future__ import annotations

import base64
import io
import logging
from pathlib import Path
from urllib.parse import quote

from factory.store import atomic_write_bytes

log = logging.getLogger(__name__)

FILES_DIR = "report_files"
"""Folder of the page's own files (``embed=false``), relative to the run directory."""


class MediaSink:
    """Turns image bytes into a ``src`` for the page.

    Args:
        run_dir: the run directory (the page is ``run_dir/report.html``).
        embed: data URIs (true) or files under ``run_dir/report_files`` (false).
    """

    def __init__(self, run_dir: Path, embed: bool) -> None:
        self.run_dir = run_dir
        self.embed = embed
        self.bytes_embedded = 0
        self.files: list[Path] = []

    def add(self, data: bytes, name: str, mime: str) -> str:
        """The ``src`` of an image.

        Args:
            data: the encoded image (PNG, JPEG, GIF bytes).
            name: its file name under ``report_files/`` (``embed=false``); may hold ``/``.
            mime: its media type (``image/png``, ``image/jpeg``, ``image/gif``).
        """
        if self.embed:
            self.bytes_embedded += len(data)
            return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"
        path = self.run_dir / FILES_DIR / name
        atomic_write_bytes(path, data)
        self.files.append(path)
        return quote(f"{FILES_DIR}/{name}")

    def link(self, path: Path) -> str:
        """A relative ``href`` from the page to a file of the run directory."""
        return quote(str(path.relative_to(self.run_dir)))


def thumbnail(path: Path, width: int) -> bytes:
    """A JPEG of the image at ``path``, scaled down to ``width`` px (aspect kept; never up).

    Raises:
        OSError: the image cannot be read (PIL's ``UnidentifiedImageError`` is one).
    """
    from PIL import Image

    with Image.open(path) as src:
        im = src.convert("RGB")
    if im.width > width:
        size = (width, max(1, round(im.height * width / im.width)))
        im = im.resize(size, Image.Resampling.LANCZOS)
    buf = io.BytesIO()
    im.save(buf, format="JPEG", quality=85, optimize=True)
    return buf.getvalue()
