"""Blender as a Python module (the `bpy` wheel, Blender 5.0), headless, with timbre's
extension installed from the zip that build.py writes, as a user installs it.

TIMBRE_BLENDER_EXTENSION names a zip already built (scripts/test builds one from the
wheel it tests); without it, build.py builds one here. TIMBRE_BIN names the `timbre`
command (default: target/release/timbre). Blender's user folders are a temporary
folder, so the tests leave the user's Blender alone.
"""

import atexit
import os
import shutil
import subprocess
import sys
import tempfile

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.abspath(os.path.join(HERE, "..", "..", "..", ".."))
SHOTS = os.path.join(REPO, "examples", "shots")

# Blender reads its user folders (extensions, preferences) from $HOME when bpy is
# imported: a fresh one per run.
_home = tempfile.mkdtemp(prefix="timbre-blender-home-")
os.environ["HOME"] = _home
atexit.register(shutil.rmtree, _home, ignore_errors=True)

import bpy  # noqa: E402  (after HOME is set)

MODULE = "bl_ext.user_default.timbre"


def timbre_command():
    return os.environ.get("TIMBRE_BIN") or os.path.join(REPO, "target", "release", "timbre")


@pytest.fixture(scope="session")
def extension_zip(tmp_path_factory):
    built = os.environ.get("TIMBRE_BLENDER_EXTENSION")
    if built:
        return built
    out = str(tmp_path_factory.mktemp("extension") / "timbre-extension.zip")
    subprocess.run([sys.executable, os.path.join(REPO, "crates", "timbre-python", "blender",
                                                 "build.py"), out], check=True)
    return out


@pytest.fixture(scope="session")
def installed(extension_zip):
    """Installs and enables the extension once; returns its module name."""
    result = bpy.ops.extensions.package_install_files(
        filepath=extension_zip, repo="user_default", enable_on_install=True)
    assert result == {"FINISHED"}, result
    return MODULE


def enable(module):
    """Enables the extension again (loading factory settings turns add-ons off)."""
    import addon_utils

    addon_utils.enable(module, default_set=True, handle_error=None)
    assert hasattr(bpy.types.Object, "timbre"), "the extension did not register"


def load_script(name, path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
