"""The scene files of the repository, installed as the package data `raytrace.scenes`."""
