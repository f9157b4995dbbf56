"""Build timbre's Blender extension: an installable zip holding the extension's
Python files, its manifest and the `timbre` wheel built for this platform.

    python3 crates/timbre-python/blender/build.py OUT.zip [--wheel WHEEL]

Without --wheel the wheel is built from crates/timbre-python with pip (maturin and
cargo, as `pip install ./crates/timbre-python` builds it). Install the zip in
Blender 4.2 or later: Edit → Preferences → Get Extensions → Install from Disk, or
`blender --command extension install-file -r user_default OUT.zip`.
"""

import argparse
import glob
import os
import re
import subprocess
import sys
import tempfile
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = os.path.dirname(HERE)
EXTENSION = os.path.join(HERE, "extension")

# A wheel's platform tag, and Blender's name for that platform.
PLATFORMS = (
    (r"(many|musl)?linux.*_x86_64$", "linux-x64"),
    (r"(many|musl)?linux.*_aarch64$", "linux-arm64"),
    (r"macosx_.*_(arm64|universal2)$", "macos-arm64"),
    (r"macosx_.*_x86_64$", "macos-x64"),
    (r"win_amd64$", "windows-x64"),
    (r"win_arm64$", "windows-arm64"),
)


def build_wheel(folder):
    """Builds the `timbre` wheel into `folder` and returns its path."""
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                    "--disable-pip-version-check", "--wheel-dir", folder, PACKAGE], check=True)
    wheels = glob.glob(os.path.join(folder, "timbre-*.whl"))
    if len(wheels) != 1:
        sys.exit(f"build.py: expected one timbre wheel in {folder}, found {wheels}")
    return wheels[0]


def platform_of(wheel):
    """Blender's platform name for a wheel, from its file name's platform tag."""
    tag = os.path.basename(wheel)[:-len(".whl")].split("-")[-1]
    for pattern, platform in PLATFORMS:
        if any(re.search(pattern, part) for part in tag.split(".")):
            return platform
    sys.exit(f"build.py: Blender has no platform for the wheel tag {tag!r}")


def version_of(wheel):
    """The wheel's version (timbre-VERSION-...)."""
    return os.path.basename(wheel).split("-")[1]


def write_zip(out, wheel):
    manifest = open(os.path.join(EXTENSION, "blender_manifest.toml"), encoding="utf-8").read()
    manifest = (manifest.replace("@VERSION@", version_of(wheel))
                .replace("@PLATFORM@", platform_of(wheel))
                .replace("@WHEEL@", os.path.basename(wheel)))
    folder = os.path.dirname(os.path.abspath(out))
    os.makedirs(folder, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=".timbre-", suffix=".zip", dir=folder)
    os.close(handle)
    try:
        with zipfile.ZipFile(temporary, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("blender_manifest.toml", manifest)
            for path in sorted(glob.glob(os.path.join(EXTENSION, "*.py"))):
                archive.write(path, os.path.basename(path))
            archive.write(wheel, "wheels/" + os.path.basename(wheel))
        os.replace(temporary, out)
    except BaseException:
        os.remove(temporary)
        raise


def main():
    parser = argparse.ArgumentParser(description="Build timbre's Blender extension zip.")
    parser.add_argument("out", help="the zip to write")
    parser.add_argument("--wheel", help="a timbre wheel already built (default: build one)")
    args = parser.parse_args()
    if args.wheel:
        write_zip(args.out, os.path.abspath(args.wheel))
    else:
        with tempfile.TemporaryDirectory() as folder:
            write_zip(args.out, build_wheel(folder))
    print(args.out)


if __name__ == "__main__":
    main()
