#!/usr/bin/env python3
"""Entry point: `python render.py [command] ...` (see README.md and `python render.py --help`)."""
import sys

from raytrace.cli import run

if __name__ == "__main__":
    sys.exit(run())
