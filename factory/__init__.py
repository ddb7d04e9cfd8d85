"""factory: a GPU-parallel batch data factory for robot policy training.

``import factory`` is cheap: it imports no jax, torch, warp, ompl or lerobot, and does no I/O.
Run stages with ``python -m factory stage=<name>``; the data contracts are in
:mod:`factory.schema`, the run directory in :mod:`factory.store`.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
