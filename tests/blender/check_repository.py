"""Installs the add-on from a static extension repository (dist/repository, scripts/package.sh)
the way a studio's artists do: the repository added once as a remote one (here a shared
folder, file://), synced, and the extension installed from it; Blender picks this platform's
zip from the repository's index.json. Then the checks of check_install.py. Argument: the
repository folder. Run with BLENDER_USER_* pointing at a temporary folder (tests/test_blender.py
does)."""
import os
import pathlib
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_install import installed_checks, report  # noqa: E402


def main():
    repo_dir = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
    url = pathlib.Path(os.path.abspath(repo_dir), "index.json").as_uri()   # file:///... on every system
    # Installing from a remote repository asks for online access, as the preferences' prompt
    # does (a file:// repository then reads the shared folder, nothing goes online).
    bpy.context.preferences.system.use_online_access = True
    repos = bpy.context.preferences.extensions.repos
    r_add = bpy.ops.preferences.extension_repo_add(name="Studio", remote_url=url, type='REMOTE')
    index = next((i for i, r in enumerate(repos) if r.remote_url == url), None)
    checks = [("repository added", r_add == {'FINISHED'} and index is not None, r_add)]
    if index is not None:
        r_sync = bpy.ops.extensions.repo_sync(repo_index=index)
        checks.append(("repository synced", r_sync == {'FINISHED'}, r_sync))
        r = bpy.ops.extensions.package_install(repo_index=index, pkg_id="smooth_ffd",
                                               enable_on_install=True)
        installed = os.path.join(repos[index].directory, "smooth_ffd")
        checks.append(("installed into the repository's folder", os.path.isdir(installed), installed))
        checks += installed_checks(r)
    report(checks)


main()
