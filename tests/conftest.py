"""Test session set-up: the repository root on sys.path so the suite runs from a plain checkout too."""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
