"""Image files: PNG encoding and contact sheets of equally sized RGB images."""

from __future__ import annotations

import io
import math

import numpy as np


def png_bytes(image: np.ndarray) -> bytes:
    """PNG encoding of an RGB image."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def contact_sheet(images: dict[str, np.ndarray], columns: int = 3) -> np.ndarray:
    """Tiles equally sized images into one (row-major, white gaps)."""
    ims = list(images.values())
    h, w, _ = ims[0].shape
    rows = math.ceil(len(ims) / columns)
    gap = 4
    sheet = np.full(
        (rows * h + (rows - 1) * gap, columns * w + (columns - 1) * gap, 3), 255, np.uint8
    )
    for i, im in enumerate(ims):
        r, c = divmod(i, columns)
        sheet[r * (h + gap) : r * (h + gap) + h, c * (w + gap) : c * (w + gap) + w] = im
    return sheet


__all__ = ["contact_sheet", "png_bytes"]
