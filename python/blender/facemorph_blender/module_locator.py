"""Finding the `facemorph` Python module from inside Blender.

Blender 3.4 as Debian packages it runs on the system Python 3.11, so the module built for
/usr/bin/python3 (build/python/facemorph, or a pip install) loads into it unchanged. It is looked
for, in this order:

1. the add-on's preference "Module folder" (the folder that holds `facemorph/`, e.g. build/python
   or a venv's site-packages);
2. the environment variable FACEMORPH_PYTHONPATH (folders separated by os.pathsep), for scripts and
   `blender -b` runs that start from factory settings;
3. Blender's own sys.path (a system-wide `pip install --break-system-packages ./python` lands in
   /usr/local/lib/python3.11/dist-packages, which Debian's Blender searches).
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import List, Optional

ENV_VARIABLE = "FACEMORPH_PYTHONPATH"


class ModuleNotFound(Exception):
    """The facemorph module could not be imported; the message says where it was looked for."""


def candidate_folders(preference_folder: Optional[str]) -> List[str]:
    """Folders to put in front of sys.path, the preference's first."""
    folders = []
    if preference_folder:
        folders.append(os.path.abspath(bpy_path_abs(preference_folder)))
    for entry in os.environ.get(ENV_VARIABLE, "").split(os.pathsep):
        if entry:
            folders.append(os.path.abspath(entry))
    return folders


def bpy_path_abs(path: str) -> str:
    # A preference may be written relative to the .blend ("//..."); outside Blender it is a plain path.
    try:
        import bpy
        return bpy.path.abspath(path)
    except ImportError:
        return path


def import_facemorph(preference_folder: Optional[str] = None):
    """The facemorph module, or ModuleNotFound saying where it looked and why it failed."""
    module = sys.modules.get("facemorph")
    if module is not None:
        return module
    folders = candidate_folders(preference_folder)
    for folder in reversed(folders):
        if folder not in sys.path:
            sys.path.insert(0, folder)
    try:
        return importlib.import_module("facemorph")
    except ImportError as error:
        # A module found but unloadable (built for another Python, numpy missing) says so: its
        # message is more useful than "not found".
        looked = ", ".join(folders) + ", then " if folders else ""
        raise ModuleNotFound(
            f"the facemorph Python module cannot be imported ({error}); looked in {looked}Blender's sys.path "
            f"(the add-on's 'Module folder' preference first, then ${ENV_VARIABLE}). Build it (cmake "
            f"option FACEMORPH_PYTHON, target facemorph_python: build/python) or pip install ./python, and "
            f"set the preference to the folder that holds facemorph/") from None
