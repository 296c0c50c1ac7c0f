#!/usr/bin/env python3
"""Makes the Blender add-on's zip: make_addon_zip.py [OUT.zip] (default facemorph_blender.zip).

Install it with Blender's Preferences > Add-ons > Install..., or from a script:
    bpy.ops.preferences.addon_install(filepath=OUT.zip); bpy.ops.preferences.addon_enable(module="facemorph_blender")
The zip holds the folder facemorph_blender/ (its .py files), with fixed dates so the same sources
make the same bytes.
"""

import pathlib
import sys
import zipfile

ADDON = pathlib.Path(__file__).resolve().parent / "facemorph_blender"


def make_zip(out: pathlib.Path) -> pathlib.Path:
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(out.name + ".partial")
    with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for source in sorted(ADDON.glob("*.py")):
            entry = zipfile.ZipInfo(f"{ADDON.name}/{source.name}", date_time=(2024, 1, 1, 0, 0, 0))
            entry.compress_type = zipfile.ZIP_DEFLATED
            entry.external_attr = 0o644 << 16
            archive.writestr(entry, source.read_bytes())
    partial.replace(out)  # never a half-written zip under the final name
    return out


if __name__ == "__main__":
    target = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "facemorph_blender.zip")
    print(make_zip(target))
