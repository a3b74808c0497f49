"""Mesh <-> numpy transfer for the add-on: foreach_get/foreach_set only, never a loop per vertex.

Positions are read from and written to the *base* mesh (``mesh.vertices``), the data the user
owns; modifiers are evaluated on top of it. Blender stores float32, the core works in float64.
"""

from __future__ import annotations

import numpy as np

CARRIER_GROUP = "pmwm_carriers"


def read_positions(mesh) -> np.ndarray:
    """(n, 3) float64 vertex positions of the base mesh (object space)."""
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def read_positions32(mesh) -> np.ndarray:
    """(n, 3) float32 positions exactly as stored (used to detect later edits)."""
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def read_triangles(mesh) -> np.ndarray:
    """(m, 3) int64 triangulation of all faces (quads and n-gons included) in mesh vertex indices."""
    mesh.calc_loop_triangles()
    tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    return tris.reshape(-1, 3).astype(np.int64)


def write_base_positions(mesh, vertices: np.ndarray) -> None:
    """Replace the base positions; shape keys get the same displacement so every key mix keeps it.

    The topology (vertices, edges, quads, n-gons) is untouched: only coordinates change.
    """
    new = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1)
    keys = mesh.shape_keys
    if keys is not None:
        old = np.empty_like(new)
        mesh.vertices.foreach_get("co", old)
        delta = new.astype(np.float64) - old
        buf = np.empty_like(new)
        for block in keys.key_blocks:
            if block == keys.reference_key:
                block.data.foreach_set("co", new)
            else:
                block.data.foreach_get("co", buf)
                block.data.foreach_set("co", (buf + delta).astype(np.float32))
    mesh.vertices.foreach_set("co", new)
    mesh.update()


def set_geometry(mesh, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Replace the whole geometry of ``mesh`` by a triangle mesh, in place (same datablock)."""
    n, m = len(vertices), len(faces)
    mesh.clear_geometry()
    mesh.vertices.add(n)
    mesh.loops.add(3 * m)
    mesh.polygons.add(m)
    mesh.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1))
    mesh.loops.foreach_set("vertex_index", np.ascontiguousarray(faces, dtype=np.int32).reshape(-1))
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * m, 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(m, 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    if m and hasattr(mesh, "shade_smooth"):
        mesh.shade_smooth()


def mark_carriers(ob, carriers: np.ndarray) -> None:
    """Put the carrier vertices in the temporary vertex group ``pmwm_carriers`` (replacing it)."""
    clear_carriers(ob)
    group = ob.vertex_groups.new(name=CARRIER_GROUP)
    group.add(np.asarray(carriers, dtype=np.int64).tolist(), 1.0, "REPLACE")


def clear_carriers(ob) -> bool:
    """Remove the ``pmwm_carriers`` vertex group if present; True when one was removed."""
    group = ob.vertex_groups.get(CARRIER_GROUP)
    if group is None:
        return False
    ob.vertex_groups.remove(group)
    return True
