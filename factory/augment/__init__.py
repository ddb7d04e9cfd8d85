"""Scene augmentation: configuration-, category- and layout-level variants (``stage=augment``).

Import :mod:`factory.augment.levels` for the level functions; this package imports nothing
heavy.
"""
