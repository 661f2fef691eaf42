"""What leaves the renderer: EXR and PNG files (film.py), the ACES view of previews (view.py), the
tev viewer's protocol (tev.py) and image error metrics (metrics.py)."""
