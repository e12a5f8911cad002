import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, HERE)

# tests/blender/ holds scripts that run *inside* Blender; tests/test_blender.py drives them.
collect_ignore = ["blender"]
