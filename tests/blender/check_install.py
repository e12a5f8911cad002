"""Installs the add-on zip (dist/, scripts/package.sh) the way users do: as an extension on
4.2+ (Install from Disk) and as a legacy add-on before; then checks that it registered, that
it runs its *bundled* core, and that a Smooth FFD modifier works. Argument: the zip.
Run with BLENDER_USER_* pointing at a temporary folder (tests/test_blender.py does)."""
import importlib
import os
import sys

import bpy

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def installed_checks(r):
    """The checks after an install operator returned `r`: the add-on registered, runs its
    bundled core, and a Smooth FFD modifier works."""
    names = [m for m in sys.modules if m == "smooth_ffd" or m.endswith(".smooth_ffd")]
    checks = [("install operator finished", r == {'FINISHED'}, r),
              ("add-on module loaded", bool(names), names)]
    if names:
        addon = sys.modules[names[0]]
        getter = getattr(getattr(addon, "core", None), "smoothffd", None)
        core_file = (getter() if getter else importlib.import_module("smoothffd")).__file__
        here = os.path.realpath(ROOT) + os.sep
        checks.append(("bundled core used (not the source tree's)",
                       not os.path.realpath(core_file).startswith(here), core_file))
        checks.append(("operator registered", hasattr(bpy.ops.object, "smooth_ffd_add"), ""))
        bpy.ops.mesh.primitive_cube_add()
        obj = bpy.context.object
        lat_obj = bpy.data.objects.new("lat", bpy.data.lattices.new("lat"))
        bpy.context.scene.collection.objects.link(lat_obj)
        lat_obj.scale = (2, 2, 2)
        mod = addon.add_smooth_ffd(obj, lat_obj, 2, 2)
        checks.append(("modifier works", addon.status(mod).startswith("OK"), addon.status(mod)))
    return checks


def report(checks):
    failed = 0
    for name, ok, detail in checks:
        print(f"{'PASS' if ok else 'FAIL'} {name} {detail}")
        failed += not ok
    print(f"{len(checks) - failed} passed, {failed} failed")
    sys.stdout.flush()
    if not bpy.app.binary_path:   # PyPI bpy: skip exit()'s destructors (sffd_testlib.exit_now)
        os._exit(1 if failed else 0)
    if failed:
        raise SystemExit(1)


def main():
    zip_path = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
    if bpy.app.version >= (4, 2):
        r = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                     enable_on_install=True)
    else:
        bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
        r = bpy.ops.preferences.addon_enable(module="smooth_ffd")
    report(installed_checks(r))


if __name__ == "__main__":
    main()
