"""Physics: Scene -> MjSpec/MjModel (``compile``), wall geometry, surface materials.

Import submodules directly (``from factory.sim.compile import compile_scene``); this package
imports nothing heavy.
"""
