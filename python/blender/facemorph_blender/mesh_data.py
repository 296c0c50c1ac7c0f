"""Decoded frames (numpy arrays) into Blender meshes, through foreach_set: no Python loop per vertex.

The mesh's vertices are the decoded positions exactly (float32, the file's units); the object's
transform turns the capture's y-up frame into Blender's z-up one and scales it to metres, so
comparing a mesh with `fmdec -o frame.obj` needs no conversion.
"""

from __future__ import annotations

import numpy as np


def build_topology(mesh, positions: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> None:
    """Replaces the mesh's geometry with these vertices, triangles and per-vertex UVs."""
    mesh.clear_geometry()
    vertex_count, triangle_count = len(positions), len(faces)
    mesh.vertices.add(vertex_count)
    mesh.vertices.foreach_set("co", np.ascontiguousarray(positions, dtype=np.float32).ravel())
    corners = np.ascontiguousarray(faces, dtype=np.int32).ravel()
    mesh.loops.add(len(corners))
    mesh.loops.foreach_set("vertex_index", corners)
    mesh.polygons.add(triangle_count)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * triangle_count, 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(triangle_count, 3, dtype=np.int32))
    # A face is a smooth surface: Blender's vertex normals, not facets.
    mesh.polygons.foreach_set("use_smooth", np.ones(triangle_count, dtype=bool))
    mesh.update(calc_edges=True)
    if uv is not None:
        layer = mesh.uv_layers.new(name="UVMap") if not mesh.uv_layers else mesh.uv_layers[0]
        layer.data.foreach_set("uv", np.ascontiguousarray(uv[corners], dtype=np.float32).ravel())


def set_positions(mesh, positions: np.ndarray) -> bool:
    """Moves the vertices of a mesh whose topology is the frame's; False where the counts differ."""
    if len(mesh.vertices) != len(positions):
        return False
    mesh.vertices.foreach_set("co", np.ascontiguousarray(positions, dtype=np.float32).ravel())
    mesh.update()
    return True


def vertex_positions(mesh) -> np.ndarray:
    """The mesh's vertex coordinates as an (n, 3) float32 array."""
    out = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", out)
    return out.reshape(-1, 3)
