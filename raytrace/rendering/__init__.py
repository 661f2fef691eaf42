"""The render loop: tiles, their fixed reduction order and the thread pool (renderer.py), output
layers (aov.py), progressive passes and checkpoints (progressive.py), and the Dask cluster's tasks
(distributed.py, plugged in by api.py)."""
