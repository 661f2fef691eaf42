"""Volumetric shadows: the exact lit intervals of a segment seen from each light (frusta.py), the lit
pieces of a beam of rays behind a boundary (beams.py), and the classic shadow ray per medium point
of the methods that expose their points (shadow_rays.py)."""
