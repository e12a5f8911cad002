"""Runs blender_scenes/bench_addon.py (its arguments after this script's) with the add-on that
sffd_testlib loads: the source tree's, or the installed one (SFFD_TEST_ADDON_ZIP). The bench
imports `smooth_ffd` by name and registers it; here that name is the loaded add-on, and an
installed add-on, registered when it was enabled, is not registered twice."""
import os
import runpy
import sys

import bpy  # noqa: F401  (first: the bpy module puts bmesh on sys.path)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402

addon = T.smooth_ffd
if T.INSTALLED:
    sys.modules["smooth_ffd"] = addon
    for name in T.MODULES:
        sys.modules["smooth_ffd." + name] = getattr(T, name)
    addon.register = lambda: None
    T.setup()
    if not all(ok for _, ok in T._results):   # the installed add-on or core is the source tree's
        T.finish()
runpy.run_path(os.path.join(T.ROOT, "blender_scenes", "bench_addon.py"), run_name="__main__")
T.exit_now(0)
