"""Builds every demo scene in one Blender session and saves each as OUT/<scene>.blend.

    blender -b --factory-startup --python-exit-code 1 --python blender_scenes/build_all.py \
        -- [--out DIR] [--only vase,teapot]
"""
import importlib
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

SCENES = ("vase", "cube", "teapot", "suzanne", "chess", "knotbox")


def main():
    args = common.script_args()
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    only = argv[argv.index("--only") + 1].split(",") if "--only" in argv else SCENES
    common.enable_addon()
    for name in only:
        t0 = time.perf_counter()
        common.clear()
        demo = importlib.import_module(name).build()
        common.save(demo, args["out"])
        print(f"built {name} in {time.perf_counter() - t0:.1f} s")


main()
