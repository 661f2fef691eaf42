"""Where rays meet shapes: Embree's triangle meshes (accel.py, the only module that imports embreex)
and the facet walk through convex meshes that finds the kinks of light paths (facet_walk.py)."""
