"""Scene generation and scene artifacts (ingest, renders, SAGE meshes).

Submodules are imported where they are used; this package imports nothing heavy.
"""
