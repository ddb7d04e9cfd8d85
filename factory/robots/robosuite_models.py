"""The Panda composed from robosuite's MJCF model classes, and where its caches are kept.

Both robots, the fixed-base Panda (:mod:`factory.robots.panda`) and the Panda on the Omron
mobile base (:mod:`factory.robots.mobile_panda`), are composed here from robosuite's model
classes (its environment runtime is not used) and exported once to a cache directory under
``FACTORY_ROBOT_CACHE`` whose name carries the robosuite version and :data:`CACHE_KEY`.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from factory.robots.visual_mesh import SIMPLIFY_VERSION, VISUAL_FACES

log = logging.getLogger(__name__)

ROBOSUITE_VERSION = "1.5.1"


CACHE_KEY = f"vis{VISUAL_FACES}-s{SIMPLIFY_VERSION}"
"""Part of the robot caches' directory names: caches made with other visual meshes (another
face budget or simplification) are not read, and a new one is made."""


def robosuite_cache_dir(name: str) -> Path:
    """The cache directory of the composed model ``name`` (``panda``, ``panda-omron``) under
    ``FACTORY_ROBOT_CACHE`` (default ``~/.cache/factory/robots``):
    ``{name}-robosuite-{ROBOSUITE_VERSION}-{CACHE_KEY}``."""
    root = os.environ.get("FACTORY_ROBOT_CACHE") or "~/.cache/factory/robots"
    return Path(root).expanduser() / f"{name}-robosuite-{ROBOSUITE_VERSION}-{CACHE_KEY}"


def robosuite_panda_xml(
    base: str | None = None, what: str = "robot model", cache: Path | None = None
) -> str:
    """The Panda + Panda gripper MJCF from robosuite's model classes (absolute mesh paths).

    Args:
        base: the name of a class in ``robosuite.models.bases`` to stand the arm on
            (``OmronMobileBase``); None for robosuite's default fixed mount.
        what: the model's name in the error raised without robosuite.
        cache: a robot cache that would serve instead, named in that error; None for none.

    Raises:
        ConfigError: robosuite cannot be imported.
    """
    # robosuite logs set-up hints on import (macros, optional robots); they are not ours.
    for name in ("robosuite", "robosuite_logs"):
        logging.getLogger(name).setLevel(logging.ERROR)
    try:
        import robosuite
        from robosuite.models import bases
        from robosuite.models.grippers import PandaGripper
        from robosuite.models.robots import Panda
    except ImportError as e:  # pragma: no cover - the demos extra is part of setup.sh
        from factory.errors import ConfigError

        or_cache = f" or a robot cache at {cache}" if cache is not None else ""
        raise ConfigError(
            f"the {what} needs robosuite {ROBOSUITE_VERSION} ({e}){or_cache}: "
            "pip install -e '.[demos]'"
        ) from None
    if robosuite.__version__ != ROBOSUITE_VERSION:
        log.warning(
            "robosuite %s, models expected from %s", robosuite.__version__, ROBOSUITE_VERSION
        )
    robot = Panda()
    if base is not None:
        robot.add_base(getattr(bases, base)())
    robot.add_gripper(PandaGripper())
    return str(robot.get_xml())
