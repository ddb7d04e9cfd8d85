"""LeRobot datasets from recorded episodes (``stage=dataset``).

Importing this package imports numpy only; lerobot is imported by the functions that write.
"""

from factory.dataset.card import write_card
from factory.dataset.features import features_for
from factory.dataset.lerobot_export import (
    export_store,
    merge_datasets,
    pack_depth_mm,
    unpack_depth_mm,
)
from factory.dataset.routes import episode_routes
from factory.dataset.video import VideoCodec, lossless_codec, rgb_codec

__all__ = [
    "VideoCodec",
    "episode_routes",
    "export_store",
    "features_for",
    "lossless_codec",
    "merge_datasets",
    "pack_depth_mm",
    "rgb_codec",
    "unpack_depth_mm",
    "write_card",
]
